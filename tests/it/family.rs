//! Acceptance tests of issue #10 on the independent drives of `biasctl::family`: drives
//! whose pivot, position trend, noise and memory law differ from the built-in drive, each with
//! hidden effects of every class and three logged columns that have no effect. The scoring code
//! is `examples/diagnose_family.rs` (included, so the README scoreboard and these tests are the
//! same code); the tests run a rotation of drives × scenarios on fixed seeds, the example runs
//! them all over many seeds.

#[path = "../../examples/diagnose_family.rs"]
#[allow(dead_code)]
pub(crate) mod diagnose_family;

use biasctl::{family::FamilyDrive, family::HiddenEffect};
use diagnose_family::{Outcome, full_model_flags, run, scenarios};

/// Seeks per log in the tests (the scoreboard uses 2000).
const N: usize = 1500;

/// Scenario `i` on drive `i mod 3`, seed `100 + i`: every scenario once, every drive four times.
fn rotation() -> Vec<Outcome> {
    let drives = FamilyDrive::members();
    scenarios()
        .iter()
        .enumerate()
        .map(|(i, effects)| run(&drives[i % drives.len()], effects, 100 + i as u64, N))
        .collect()
}

fn describe(o: &Outcome) -> String {
    let names: Vec<&str> = o.effects.iter().map(|e| e.name()).collect();
    format!(
        "{} {} seed {}: first {:?}, edit {:?}, std {:.3} -> {:.3} (true term {:?}), recovered \
         {:?} (unverified suggestion {:?}: {:?}); scored: {}",
        o.drive,
        names.join("+"),
        o.seed,
        o.first,
        o.edit,
        o.std_base,
        o.std_edit,
        o.std_true,
        o.recovered(),
        o.suggested,
        o.recovered_by_suggestion(),
        o.verification
    )
}

/// Issue #10's bar: every scenario right first, every first edit ≥ 90 % of the achievable.
const ISSUE_SCENARIOS: usize = 12;
/// Known gap (README, "Independent drives for testing diagnosis"): what diagnose reaches today
/// on this rotation; the test fails if it falls below, and the README says what is missing.
/// (7 and 5 before the strongest unflagged features were verified by refit; 10 and 9 since;
/// 11 and 10 since the `bump` term resolves the narrow defect; 11 and 11 since the
/// verification's z-score is taken on the noise part of the paired loss difference: the
/// `bw1-sine-tar` threshold run's `bins:load:16`, 6.6 % at z = 1.2 before, is verified at 2.4;
/// 12 of 12 since the interaction is scored too, against its true term `by:position:supply`.)
const KNOWN_RIGHT_FIRST: usize = 12;
/// See [`KNOWN_RIGHT_FIRST`].
const KNOWN_RECOVERED: usize = 12;
/// Issue #10's bar for the model holding every effect: at most 1 of 20 seeds flags anything.
const ISSUE_FLAGGED_SEEDS: usize = 1;
/// Seeds of 20 allowed to flag something: the issue's bar, met since diagnose's null keeps the
/// residual's serial structure (0 of 20 today; 8 of 20 with the row-shuffling null before it).
const KNOWN_FLAGGED_SEEDS: usize = ISSUE_FLAGGED_SEEDS;

/// Reference: the generator's truth (which effect is on). The first-ranked flagged feature must
/// name a hidden effect (its column or a lag of it, `position`, a `memsum_L` feature) and the
/// first verified edit (what `diagnose_verified` leads with; none verified recovers nothing)
/// must recover at least 90 % of the residual-std reduction that refitting with the effect's
/// true term achieves. Issue #10 asks for all 12 scenarios (the interaction's true term is
/// `by:position:supply`); today's counts are asserted as a floor and every miss is printed. Before #10, diagnose named `elapsed_s` for a lagged temperature and
/// `rest_distance_*` for summed memory.
#[test]
fn right_feature_first_and_first_edit_recovers_the_achievable_reduction() {
    let outcomes = rotation();
    let mut misses = Vec::new();
    let (mut right, mut recovered) = (0, 0);
    for o in &outcomes {
        if o.right_first {
            right += 1;
        } else {
            misses.push(format!("wrong first feature: {}", describe(o)));
        }
        if o.recovered().is_some_and(|r| r >= 0.9) {
            recovered += 1;
        } else {
            misses.push(format!("edit recovers < 90 %: {}", describe(o)));
        }
        // No bump where there is no defect (a verified edit is starred in `verification`).
        assert!(
            o.effects.contains(&HiddenEffect::Defect) || !o.verification.contains("*add bump"),
            "a bump verified without a defect: {}",
            describe(o)
        );
        // No step where there is no threshold.
        assert!(
            o.effects.contains(&HiddenEffect::Threshold) || !o.verification.contains("*add step"),
            "a step verified without a threshold: {}",
            describe(o)
        );
    }
    eprintln!(
        "right first {right}/{ISSUE_SCENARIOS}, edit ≥ 90 % {recovered}/{ISSUE_SCENARIOS}\n{}",
        misses.join("\n")
    );
    assert!(
        right >= KNOWN_RIGHT_FIRST && recovered >= KNOWN_RECOVERED,
        "right first {right}/{ISSUE_SCENARIOS} (floor {KNOWN_RIGHT_FIRST}), edit ≥ 90 % \
         {recovered}/{ISSUE_SCENARIOS} (floor {KNOWN_RECOVERED}):\n{}",
        misses.join("\n")
    );
}

/// Reference: with every effect present held by its true term (and the drive's own trend and
/// pivot by `table` and `dahl:8`), the residual is noise: issue #10 asks that nothing be
/// flagged in at least 19 of 20 seeds (alpha = 1 % family-wise); today's count is the floor.
/// The diagnosis is verified and a verified edit counts as a flag, so this is also the
/// false-alarm check of verifying the strongest unflagged features.
#[test]
fn model_holding_every_effect_flags_nothing_in_19_of_20_seeds() {
    let drives = FamilyDrive::members();
    let held: Vec<Vec<HiddenEffect>> = scenarios();
    let mut flagged = Vec::new();
    for seed in 0..20u64 {
        let drive = &drives[seed as usize % drives.len()];
        let effects = &held[seed as usize % held.len()];
        let f = full_model_flags(drive, effects, 200 + seed, N);
        if !f.is_empty() {
            flagged.push(format!("{} seed {}: {f:?}", drive.name, 200 + seed));
        }
    }
    eprintln!(
        "{} of 20 seeds flag a feature (issue: ≤ {ISSUE_FLAGGED_SEEDS})\n{}",
        flagged.len(),
        flagged.join("\n")
    );
    assert!(
        flagged.len() <= KNOWN_FLAGGED_SEEDS,
        "{} of 20 seeds flag a feature (known gap: {KNOWN_FLAGGED_SEEDS}):\n{}",
        flagged.len(),
        flagged.join("\n")
    );
}

/// Reference: the generator's parameters. On a `bw-sine-t` log with the lag effect, `lag:temp_lag`
/// recovers the lag's time constant (10 s) and slope (1.2 × noise std per 3 °C = 0.8 counts/°C);
/// with summed memory, `memsum` recovers L = span/12 = 20 tracks and A = 1.2 × noise std = 2.4
/// counts. Both fitted models survive a save/load round trip with identical predictions.
#[test]
fn lag_and_memsum_terms_recover_the_generators_parameters() {
    use biasctl::{family::FamilyConfig, family::generate};
    let drive = FamilyDrive::member("bw-sine-t").unwrap();
    let base = diagnose_family::base_terms(&drive);
    let dir = tempfile::tempdir().unwrap();
    for (effect, term, checks) in [
        (
            HiddenEffect::Lag,
            "lag:temp_lag",
            [
                ("lag:temp_lag.tau", 10.0, 0.25),
                ("lag:temp_lag.slope", 0.8, 0.1),
            ],
        ),
        (
            HiddenEffect::SummedMemory,
            "memsum",
            [("memsum.L", 20.0, 0.25), ("memsum.A", 2.4, 0.15)],
        ),
    ] {
        let run = generate(&FamilyConfig::new(drive.clone(), &[effect], 31, 3000)).unwrap();
        let terms = diagnose_family::with_term(&base, term);
        let model = diagnose_family::fit_terms(&terms, &run.log);
        for (name, want, rel) in checks {
            let got = model.param(name).unwrap().value;
            assert!(
                (got - want).abs() <= rel * want,
                "{name}: {got} vs {want} (±{:.0} %)",
                rel * 100.0
            );
        }
        let path = dir.path().join(format!("{}.json", effect.name()));
        model.save(&path).unwrap();
        let back = biasctl::FittedModel::load(&path).unwrap();
        let (a, b) = (
            model.predict_log(&run.log).unwrap(),
            back.predict_log(&run.log).unwrap(),
        );
        let worst = a
            .predicted
            .iter()
            .zip(&b.predicted)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-9, "{term}: reloaded model differs by {worst}");
    }
}

/// Issue #11 item 4, `play` and interactions, each suggested as a typed edit and verified by
/// refit. Reference: the generator's physics. The `pi-cubic-ar1` pivot is a Prandtl–Ishlinskii
/// (stop-operator) loop; a model with only a direction offset (`table:S,direction`) cannot
/// express it, and the verified best edit is `play:N` (scored beside `dahl:4`). With the pivot
/// held (`table:S,dahl:8`) no `play` edit is verified. The interaction scenario's bias is
/// `supply × position`: the verified best edit is `by:position:supply`; with no interaction
/// (the fast-covariate scenario, its true term held) no `by:` edit is verified.
#[test]
fn play_and_interaction_are_suggested_where_they_apply_and_only_there() {
    use biasctl::family::{FamilyConfig, generate};
    use biasctl::{CheckedVerifyConfig, diagnose_verified};
    let drive = FamilyDrive::member("pi-cubic-ar1").unwrap();
    let run = generate(&FamilyConfig::new(drive.clone(), &[], 7, N)).unwrap();
    let table = diagnose_family::base_terms(&drive)[0].clone();
    let verified = |terms: &[String], log: &biasctl::Log, seed: u64| {
        let model = diagnose_family::fit_terms(terms, log);
        let d = diagnose_verified(
            &model,
            log,
            &diagnose_family::config(seed),
            &CheckedVerifyConfig::default(),
        )
        .unwrap();
        let v = d.verification.clone().unwrap();
        (d, v)
    };
    let (d, v) = verified(&[table.clone(), "direction".into()], &run.log, 7);
    let best = v.best().unwrap_or_else(|| panic!("{}", d.to_text()));
    assert!(best.edit.starts_with("add play"), "{}", d.to_text());
    let (d, v) = verified(&diagnose_family::base_terms(&drive), &run.log, 7);
    assert!(
        !v.edits
            .iter()
            .any(|e| e.verified && e.edit.contains("play")),
        "{}",
        d.to_text()
    );

    let bw = FamilyDrive::member("bw-sine-t").unwrap();
    let run = generate(&FamilyConfig::new(
        bw.clone(),
        &[HiddenEffect::Interaction],
        8,
        N,
    ))
    .unwrap();
    let (d, v) = verified(&diagnose_family::base_terms(&bw), &run.log, 8);
    let best = v.best().unwrap_or_else(|| panic!("{}", d.to_text()));
    assert!(
        best.edit.starts_with("add by:")
            && best.edit.contains("supply")
            && best.edit.contains("position"),
        "{}",
        d.to_text()
    );
    let run = generate(&FamilyConfig::new(
        bw.clone(),
        &[HiddenEffect::FastCovariate],
        8,
        N,
    ))
    .unwrap();
    let held = diagnose_family::with_term(&diagnose_family::base_terms(&bw), "col:temp_fast");
    let (d, v) = verified(&held, &run.log, 8);
    assert!(
        !v.edits.iter().any(|e| e.verified && e.edit.contains("by:")),
        "{}",
        d.to_text()
    );
}

/// Issue #10: a slowly varying column with **no** effect must not be flagged under strongly
/// autocorrelated noise. Reference: the generator's truth. `pi-cubic-ar1` logs (AR(1) noise in
/// seek order, ρ = 0.6) with the threshold effect, diagnosed (with verification) on the model
/// that holds every effect present (`table`, `dahl:8`, the true `step:load`): the random
/// walk `walk`, the warm-up curve and white noise are logged but never enter the bias, so any
/// flag or verified edit is a false alarm, and none of 6 seeds may have one. Seed 50 is the
/// held-out log where, before the within-fold gain was required, `walk@lag32.4s` was flagged
/// and `col:walk` verified (3.2 % out of sample at z = 4.2, 0.3 % within folds): this test
/// failed there.
#[test]
fn slow_no_effect_column_is_not_flagged_under_ar1_noise() {
    let drive = FamilyDrive::member("pi-cubic-ar1").unwrap();
    let mut flagged = Vec::new();
    for seed in 45..=50u64 {
        let f = full_model_flags(&drive, &[HiddenEffect::Threshold], seed, N);
        if !f.is_empty() {
            flagged.push(format!("seed {seed}: {f:?}"));
        }
    }
    assert!(flagged.is_empty(), "{}", flagged.join("\n"));
}

/// Reference: the generator's truth. The defect scenario adds `5·a·exp(−½((x − c)/1.5)²)`
/// (a = the drive's effect scale × noise std; c = the track where the truth series peaks,
/// where it equals 5·a exactly since tracks are integers). Fitting the user's model plus
/// `bump` (centre and width found from the data) on three drives must recover the centre
/// within a quarter of a track, the width within 20 % and the amplitude within 2.5 standard
/// errors; the fitted model survives a save/load round trip bit for bit.
#[test]
fn bump_term_recovers_the_generators_defect() {
    use biasctl::{family::FamilyConfig, family::generate};
    let dir = tempfile::tempdir().unwrap();
    for (i, drive) in FamilyDrive::members().into_iter().enumerate() {
        let seed = 41 + i as u64;
        let run = generate(&FamilyConfig::new(
            drive.clone(),
            &[HiddenEffect::Defect],
            seed,
            3000,
        ))
        .unwrap();
        let truth = run.truth("defect").unwrap();
        let (k, a_true) = truth
            .iter()
            .enumerate()
            .fold((0, f64::MIN), |b, (k, &v)| if v > b.1 { (k, v) } else { b });
        let c_true = run.log.tracks()[k];
        let terms = diagnose_family::with_term(&diagnose_family::base_terms(&drive), "bump");
        let model = diagnose_family::fit_terms(&terms, &run.log);
        let p = |n: &str| model.param(&format!("bump.{n}")).unwrap().clone();
        let (a, c, w) = (p("A"), p("centre"), p("width"));
        eprintln!(
            "{} seed {seed}: A {:.3} ± {:.3} (truth {a_true:.3}), centre {:.3} ± {:.3} (truth \
             {c_true}), width {:.3} ± {:.3} (truth 1.5)",
            drive.name,
            a.value,
            a.se.unwrap(),
            c.value,
            c.se.unwrap_or(f64::NAN),
            w.value,
            w.se.unwrap_or(f64::NAN)
        );
        assert!(
            (c.value - c_true).abs() < 0.25,
            "{}: centre {c:?}",
            drive.name
        );
        assert!(
            (w.value - 1.5).abs() < 0.2 * 1.5,
            "{}: width {w:?}",
            drive.name
        );
        assert!(
            (a.value - a_true).abs() < 2.5 * a.se.unwrap(),
            "{}: amplitude {a:?} vs {a_true}",
            drive.name
        );
        assert_reload_predicts_the_same_bits(&model, &run.log, dir.path(), &drive.name);
    }
}

/// Reference: the generator's truth. The threshold scenario adds `2·a` where `load > 0.6`
/// (a = the drive's effect scale × noise std: the largest value of the truth series).
/// Fitting the user's model plus `step:load` (threshold found from the data) on three drives
/// must put the threshold within 0.005 of 0.6 (2.5 % of load's std), with a profile standard
/// error, and the height within 2.5 standard errors of `2·a`; the fitted model survives a
/// save/load round trip bit for bit.
#[test]
fn step_term_recovers_the_generators_threshold() {
    use biasctl::{family::FamilyConfig, family::generate};
    let dir = tempfile::tempdir().unwrap();
    for (i, drive) in FamilyDrive::members().into_iter().enumerate() {
        let seed = 51 + i as u64;
        let run = generate(&FamilyConfig::new(
            drive.clone(),
            &[HiddenEffect::Threshold],
            seed,
            3000,
        ))
        .unwrap();
        let truth = run.truth("threshold").unwrap();
        let a_true = truth.iter().copied().fold(0.0, f64::max);
        let terms = diagnose_family::with_term(&diagnose_family::base_terms(&drive), "step:load");
        let model = diagnose_family::fit_terms(&terms, &run.log);
        let p = |n: &str| model.param(&format!("step:load.{n}")).unwrap().clone();
        let (a, t) = (p("A"), p("threshold"));
        eprintln!(
            "{} seed {seed}: A {:.3} ± {:.3} (truth {a_true:.3}), threshold {:.4} ± {:.4} \
             (truth 0.6)",
            drive.name,
            a.value,
            a.se.unwrap(),
            t.value,
            t.se.unwrap_or(f64::NAN),
        );
        assert!(
            (t.value - 0.6).abs() < 0.005,
            "{}: threshold {t:?}",
            drive.name
        );
        assert!(t.se.is_some_and(|se| se > 0.0), "{}: {t:?}", drive.name);
        assert!(
            (a.value - a_true).abs() < 2.5 * a.se.unwrap(),
            "{}: height {a:?} vs {a_true}",
            drive.name
        );
        assert_reload_predicts_the_same_bits(&model, &run.log, dir.path(), &drive.name);
    }
}

/// Issue #10's bar on the narrow defect, on every drive (seeds not in the rotation).
/// Reference: the generator's truth — the first-ranked flagged feature is `position`, the first
/// verified edit adds a `bump` whose centre lies within half a track of the track where the
/// truth series peaks, and refitting with it recovers ≥ 90 % of the reduction the true term
/// achieves.
#[test]
fn narrow_defect_is_named_first_and_its_bump_recovers_the_achievable_reduction() {
    use biasctl::{family::FamilyConfig, family::generate};
    for (i, drive) in FamilyDrive::members().into_iter().enumerate() {
        let seed = 300 + i as u64;
        let o = run(&drive, &[HiddenEffect::Defect], seed, N);
        let text = describe(&o);
        assert!(o.right_first, "{text}");
        assert!(o.recovered().is_some_and(|r| r >= 0.9), "{text}");
        let edit = o.edit.clone().unwrap_or_default();
        let centre: f64 = edit
            .strip_prefix("add bump:")
            .and_then(|r| r.split(':').next())
            .and_then(|c| c.parse().ok())
            .unwrap_or_else(|| panic!("first edit is not a bump: {text}"));
        let fam = generate(&FamilyConfig::new(
            drive.clone(),
            &[HiddenEffect::Defect],
            seed,
            N,
        ))
        .unwrap();
        let truth = fam.truth("defect").unwrap();
        let k = (0..truth.len())
            .max_by(|&a, &b| truth[a].total_cmp(&truth[b]))
            .unwrap();
        let c_true = fam.log.tracks()[k];
        assert!(
            (centre - c_true).abs() < 0.5,
            "centre {centre} vs {c_true}: {text}"
        );
    }
}

/// The lag runs the verification missed before its z-score was taken on the noise part of the
/// paired loss difference (seeds 1–5 of the study in README, "Known gap"): a lagged
/// temperature alone, and beside a position × direction effect. In each, `lag:temp_lag`
/// gained 19–56 % out of sample but at z = 1.8–2.8, under the unflagged-feature bar of 3
/// (the gain comes in episodes at set-point changes, which the block sums of the whole
/// difference counted as noise), so nothing or only `dbins:position` was verified (24–50 % of
/// the achievable). Reference: the generator's truth — the first-ranked feature reads
/// `temp_lag`, the first verified edit is the effect's own term `add lag:temp_lag`, and it
/// recovers ≥ 90 % of the reduction the best single true term achieves.
#[test]
fn a_lagged_temperature_is_verified_first_also_beside_position_direction() {
    use HiddenEffect::{Lag, PositionDirection};
    let drives = FamilyDrive::members();
    let cases: [(usize, &[HiddenEffect], u64); 5] = [
        (0, &[Lag], 5),
        (1, &[Lag], 4),
        (2, &[Lag], 1),
        (0, &[Lag, PositionDirection], 5),
        (1, &[Lag, PositionDirection], 4),
    ];
    for (d, effects, seed) in cases {
        let o = run(&drives[d], effects, seed, N);
        let text = describe(&o);
        assert!(o.right_first, "{text}");
        assert_eq!(o.edit.as_deref(), Some("add lag:temp_lag"), "{text}");
        assert!(o.recovered().is_some_and(|r| r >= 0.9), "{text}");
    }
}

/// Saves `model` as `<name>.json` in `dir`, loads it back and asserts that the reloaded model
/// predicts `log` bit for bit as the original does (the model file round trip of a searched
/// term: its found centre, width or threshold must survive the text).
fn assert_reload_predicts_the_same_bits(
    model: &biasctl::FittedModel,
    log: &biasctl::Log,
    dir: &std::path::Path,
    name: &str,
) {
    let path = dir.join(format!("{name}.json"));
    model.save(&path).unwrap();
    let back = biasctl::FittedModel::load(&path).unwrap();
    let (x, y) = (
        model.predict_log(log).unwrap(),
        back.predict_log(log).unwrap(),
    );
    assert!(
        x.predicted
            .iter()
            .zip(&y.predicted)
            .all(|(u, v)| u.to_bits() == v.to_bits()),
        "{name}: the reloaded model predicts other bits"
    );
}
