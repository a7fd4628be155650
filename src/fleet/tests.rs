//! The fleet's numbers against closed forms and slow references.

use super::*;
use crate::diagnose::DiagnoseConfig;
use crate::model::Param;
use crate::sim::{Drive, SequenceOptions, SimConfig};
use crate::{FitOptions, ModelSpec};

fn drive(name: &str, values: &[(&str, f64, Option<f64>)]) -> DriveFit {
    DriveFit {
        source: name.to_string(),
        rows: Some(100),
        terms: "poly2".into(),
        params: values
            .iter()
            .map(|&(n, value, se)| Param {
                name: n.to_string(),
                value,
                se,
            })
            .collect(),
        std: Some(1.0),
        warnings: Vec::new(),
        error: None,
    }
}

#[test]
fn robust_z_against_its_closed_form() {
    // Values 1, 2, 3, 4, 100: median 3, |deviations| 2, 1, 0, 1, 97, MAD 1, scale 1.4826.
    let rows: Vec<DriveFit> = [1.0, 2.0, 3.0, 4.0, 100.0]
        .iter()
        .enumerate()
        .map(|(i, &v)| drive(&format!("d{i}"), &[("poly2.c0", v, None)]))
        .collect();
    let found = outliers(&rows, 4.0).unwrap();
    assert_eq!(found.len(), 1);
    let o = &found[0];
    assert_eq!(
        (o.source.as_str(), o.parameter.as_str()),
        ("d4", "poly2.c0")
    );
    assert_eq!(o.median.to_bits(), 3.0f64.to_bits());
    assert!((o.sigma - 1.4826).abs() < 1e-15);
    assert!((o.z - 97.0 / 1.4826).abs() < 1e-12);
    assert_eq!(o.rule, OutlierRule::FleetSpread);
    // The drive's own standard error, larger than the fleet's spread, decides instead.
    let mut rows = rows;
    rows[4].params[0].se = Some(50.0);
    assert!(outliers(&rows, 4.0).unwrap().is_empty());
    let found = outliers(&rows, 1.5).unwrap();
    assert_eq!(found[0].rule, OutlierRule::OwnStandardError);
    assert!((found[0].z - 97.0 / 50.0).abs() < 1e-15);
    // A failed drive is left out of the median; fewer than MIN_DRIVES: not judged.
    rows[0].error = Some("unreadable".into());
    assert_eq!(outliers(&rows, 1.5).unwrap().len(), 1);
    assert!(outliers(&rows[..2], 0.1).unwrap().is_empty());
    for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let e = outliers(&rows, bad).unwrap_err().to_string();
        assert!(e.contains("Outliers::threshold"), "{e}");
    }
}

#[test]
fn the_table_reads_back_to_the_same_rows() {
    let mut rows = vec![
        drive(
            "a,\"quoted\".csv",
            &[
                ("poly2.c0", 0.1 + 0.2, Some(1e-7)),
                ("direction.b", -3.0, None),
            ],
        ),
        drive(
            "b.csv",
            &[
                ("poly2.c0", -1.5e20, None),
                ("direction.b", 2.0 / 3.0, Some(0.5)),
            ],
        ),
        DriveFit::failed(
            "c.csv",
            "c.csv: line 3, column `track`: `abc` is not a number",
        ),
    ];
    rows[1].warnings = vec!["one".into(), "two".into()];
    let text = fits_csv(&rows);
    assert!(text.starts_with(
        "source,rows,terms,poly2.c0,poly2.c0.se,direction.b,direction.b.se,std,warnings,error\n"
    ));
    assert_eq!(read_fits(&text, "fits.csv").unwrap(), rows);
    let e = read_fits(",source,rows\n", "f.csv")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("f.csv: line 1") && e.contains("index=False"),
        "{e}"
    );
    let e = read_fits("source,rows,terms,x,y,std,warnings,error\n", "f.csv")
        .unwrap_err()
        .to_string();
    assert!(e.contains("`x` must be followed by `x.se`"), "{e}");
    let bad = text.replace("b.csv,100", "b.csv,1.5");
    let e = read_fits(&bad, "f.csv").unwrap_err().to_string();
    assert!(e.contains("line 3, column `rows`"), "{e}");
}

fn simulated(seed: u64) -> crate::log::Log {
    let seeks = SequenceOptions {
        n: Some(400),
        ..SequenceOptions::default()
    };
    let sim = SimConfig::new(Drive::paper1997(), "random", &seeks, seed, &[]).unwrap();
    crate::simulate_log(&sim).unwrap()
}

fn screens(seeds: &[u64]) -> (Vec<DriveScreen>, crate::diagnose::CheckedDiagnoseConfig) {
    let drives: Vec<_> = seeds
        .iter()
        .map(|&seed| (format!("d{seed}"), simulated(seed)))
        .collect();
    screens_of(&drives)
}

/// Every drive of `drives` screened with `poly2,direction` (99 permutations), and the config.
fn screens_of(
    drives: &[(String, crate::log::Log)],
) -> (Vec<DriveScreen>, crate::diagnose::CheckedDiagnoseConfig) {
    let spec = ModelSpec::parse("poly2,direction").unwrap();
    let opts = FitOptions::default().check().unwrap();
    let config = DiagnoseConfig {
        permutations: 99,
        ..DiagnoseConfig::default()
    }
    .check()
    .unwrap();
    let s = drives
        .iter()
        .map(|(source, log)| screen_drive(source, log, &spec, &opts, &config))
        .collect();
    (s, config)
}

#[test]
fn a_pool_of_one_drive_is_that_drives_own_screen() {
    let (s, config) = screens(&[3]);
    let own = s[0].screen.as_ref().unwrap();
    let d = pool(&s, &config, &Default::default()).unwrap();
    assert_eq!(d.drives, 1);
    for f in &d.features {
        let j = own.names.iter().position(|n| n == &f.name).unwrap();
        assert_eq!(f.p_value.to_bits(), own.p_value[j].to_bits(), "{}", f.name);
        assert_eq!(f.explained.to_bits(), own.explained[j].to_bits());
        let alone = own.p_value[j] <= config.alpha && own.explained[j] > 0.0;
        assert_eq!(f.drives_alone, usize::from(alone));
    }
}

#[test]
fn the_pooled_p_values_count_the_summed_statistics() {
    let (mut s, config) = screens(&[1, 2, 5]);
    s.push(DriveScreen {
        source: "broken.csv".into(),
        screen: Err("broken.csv: line 2: no rows".into()),
    });
    let d = pool(&s, &config, &Default::default()).unwrap();
    assert_eq!(d.drives, 3);
    assert_eq!(
        d.failed,
        [(
            "broken.csv".to_string(),
            "broken.csv: line 2: no rows".to_string()
        )]
    );
    // The slow reference: sums over drives by name, counted permutation by permutation.
    let ok: Vec<&DriveStatistics> = s.iter().filter_map(|d| d.screen.as_ref().ok()).collect();
    let names = &ok[0].names;
    let b = config.permutations;
    let sum = |i: Option<usize>, name: &str| -> f64 {
        ok.iter()
            .map(|st| {
                let j = st.names.iter().position(|n| n == name).unwrap();
                if !st.tested[j] {
                    return 0.0;
                }
                match i {
                    None => st.observed[j],
                    Some(i) => st.null[i * st.names.len() + j],
                }
            })
            .sum()
    };
    let tested: Vec<&String> = names
        .iter()
        .filter(|n| {
            ok.iter()
                .any(|st| st.tested[st.names.iter().position(|m| m == *n).unwrap()])
        })
        .collect();
    for f in d.features.iter().filter(|f| f.drives > 0) {
        let obs = sum(None, &f.name);
        let raw = (0..b).filter(|&i| sum(Some(i), &f.name) <= obs).count();
        let adj = (0..b)
            .filter(|&i| {
                tested
                    .iter()
                    .map(|n| sum(Some(i), n))
                    .fold(f64::INFINITY, f64::min)
                    <= obs
            })
            .count();
        let p = |c: usize| (c as f64 + 1.0) / (b as f64 + 1.0);
        // Sums in another order may differ in the last bit: compare the counts' p-values with
        // a margin of one count.
        assert!(
            (f.p_value_raw - p(raw)).abs() <= 1.0 / (b as f64 + 1.0) + 1e-12,
            "{}",
            f.name
        );
        assert!(
            (f.p_value - p(adj)).abs() <= 1.0 / (b as f64 + 1.0) + 1e-12,
            "{}",
            f.name
        );
    }
    // The order of the drives does not matter.
    s.reverse();
    assert_eq!(pool(&s, &config, &Default::default()).unwrap(), d);
}

/// A synthetic drive whose bias is exactly `poly2,direction` plus unit noise, plus `load`
/// counts per unit of the logged `load` column (standard normal); `temp` is logged and has no
/// effect. 600 seeks: one drive alone flags a load effect of 0.2 about half the time.
fn load_drive(seed: u64, n: usize, load: f64) -> crate::log::Log {
    let mut rng = crate::numeric::rng::SimRng::new(seed);
    let mut text = String::from("time_s,track,bias,load,temp\n");
    let mut last = None;
    for i in 0..n {
        let track = rng.below(3000) as f64;
        let d = last.map_or(0.0, |l: f64| (track - l).signum());
        last = Some(track);
        let (x, temp) = (rng.normal(), rng.normal());
        let bias = 50.0 + 0.01 * track - 2e-6 * track * track + 6.0 * d + rng.normal() + load * x;
        text.push_str(&format!(
            "{},{track},{bias:.6},{x:.6},{temp:.6}\n",
            0.5 * i as f64
        ));
    }
    let name = format!("load{seed:03}.csv");
    crate::log::Log::from_reader(&name, text.as_bytes(), &crate::log::ColumnMap::default()).unwrap()
}

fn load_fleet(first: u64, drives: u64, n: usize, load: f64) -> Vec<(String, crate::log::Log)> {
    (first..first + drives)
        .map(|s| (format!("drive{s:03}"), load_drive(s, n, load)))
        .collect()
}

/// The refits of `terms` on every drive of `fleet`.
fn refits(fleet: &[(String, crate::log::Log)], terms: &[&str]) -> Vec<DriveVerification> {
    let spec = ModelSpec::parse("poly2,direction").unwrap();
    let verify = crate::select::VerifyConfig::default().check().unwrap();
    let min_effect = DiagnoseConfig::default().min_effect;
    let terms: Vec<String> = terms.iter().map(|t| t.to_string()).collect();
    fleet
        .iter()
        .flat_map(|(s, log)| verify_drive(s, log, &spec, &terms, min_effect, &verify))
        .collect()
}

/// A pooled diagnosis whose suggestion for the feature `feature` is `terms[0]`, with the
/// others as its alternatives (what the pooled screen of a fleet with that effect gives; the
/// screen itself is tested above).
fn suggesting(feature: &str, terms: &[&str]) -> FleetDiagnosis {
    let f = PooledFeature {
        name: feature.into(),
        explained: 0.01,
        p_value: 0.005,
        p_value_raw: 0.005,
        flagged: true,
        reason: "pooled_family_wise",
        drives_alone: 0,
        drives: 1,
        suggested_term: Some(terms[0].into()),
        alternatives: terms[1..].iter().map(|t| t.to_string()).collect(),
    };
    let verify = crate::select::CheckedVerifyConfig::default();
    FleetDiagnosis {
        drives: 1,
        failed: Vec::new(),
        verification: super::pooled::pending(std::slice::from_ref(&f), &verify),
        features: vec![f],
        summary: String::new(),
        alpha: 0.01,
        permutations: 199,
        seed: 1,
        best_edit: None,
    }
}

#[test]
fn one_drive_pooled_is_its_own_verification_by_diagnose() {
    // Strong enough that the drive's own diagnosis flags `load` and verifies its edit: the
    // fleet's figures of one drive are that verification's gain and z, bit for bit.
    let log = load_drive(11, 600, 0.5);
    let spec = ModelSpec::parse("poly2,direction").unwrap();
    let opts = FitOptions::default().check().unwrap();
    let model = crate::fit::fit(&spec, &log, &opts).unwrap();
    let config = DiagnoseConfig::default().check().unwrap();
    let verify = crate::select::VerifyConfig::default().check().unwrap();
    let own = crate::select::diagnose_verified(&model, &log, &config, &verify).unwrap();
    let v = own.verification.unwrap();
    let e = v.edits.iter().find(|e| e.edit == "add col:load").unwrap();
    let mut d = suggesting("load", &["col:load"]);
    let r = verify_drive(
        "d",
        &log,
        &spec,
        &["col:load".into()],
        config.min_effect,
        &verify,
    );
    pool_verifications(&mut d, &r);
    let f = &d.verification;
    assert_eq!(f.drives, 1);
    // Σ reductions / Σ before is 1 − MSE_after / MSE_before in another order of operations.
    assert!((f.gain.unwrap() - e.gain).abs() < 1e-15, "{f:?} {e:?}");
    assert_eq!(f.per_drive[0].gain.to_bits(), e.gain.to_bits());
    assert_eq!(f.z.unwrap().to_bits(), e.z.to_bits());
    assert_eq!(
        f.per_drive[0].gain_within_folds.to_bits(),
        e.gain_within_folds.to_bits()
    );
    assert_eq!(f.per_drive[0].verified_alone, e.verified);
    assert_eq!(f.edit.as_deref(), Some(e.edit.as_str()));
    assert_eq!(f.terms.as_deref(), Some(e.terms.as_str()));
    assert!(f.verified && e.verified, "{}", f.why);
    assert_eq!(d.best_edit.as_deref(), Some("col:load"));
}

#[test]
fn a_weak_effect_in_every_drive_is_verified_by_the_fleet_not_by_single_drives() {
    // 0.08 counts per unit of load on unit noise, a quarter of what one drive of 600 seeks
    // needs. Each drive's refit pays its estimate's variance out of sample (1/400 of the
    // noise at 400 training rows, 40 % of the effect's 0.0064), so the fleet's z grows as
    // about 0.3 √drives (the drives' own z average 0.15 here): over ten fleets of each size
    // (first seeds 1000, 1200, …, 2800) the fleet's z of the chosen term was 0.1–4.6 for 32
    // drives (5 of 10 verified), 2.1–5.5 for 64 (10 of 10), 2.7–6.8 for 128 (10 of 10).
    // 96 drives here (z = 3.10), for a margin.
    // The candidates as the pooled screen gives them for a covariate: every one is scored
    // (the shape `bins:load` pays for its knots), the largest fleet gain kept.
    let cands = ["bins:load", "col:load", "lag:load"];
    let fleet = load_fleet(100, 96, 600, 0.08);
    let drives = refits(&fleet, &cands);
    let mut d = suggesting("load", &cands);
    pool_verifications(&mut d, &drives);
    let v = &d.verification;
    assert!(v.try_all);
    assert_eq!(v.tried.len(), 3);
    let best = v
        .tried
        .iter()
        .map(|t| t.gain.unwrap())
        .fold(f64::MIN, f64::max);
    assert_eq!(v.gain, Some(best), "{:?}", v.tried);
    assert_eq!(v.term.as_deref(), Some("col:load"), "{:?}", v.tried);
    assert_eq!((v.drives, v.failed.len()), (96, 0));
    // The slow reference: the rule's sums taken again from each drive's figures.
    let ok: Vec<&DriveEdit> = drives
        .iter()
        .filter(|r| r.term == "col:load")
        .map(|r| r.result.as_ref().unwrap())
        .collect();
    assert_eq!(ok.len(), 96);
    let before: f64 = ok.iter().map(|e| e.sse_before).sum();
    let after: f64 = ok.iter().map(|e| e.sse_after).sum();
    let t: f64 = ok.iter().map(|e| e.loss_gain).sum();
    let s2: f64 = ok.iter().map(|e| e.loss_se * e.loss_se).sum();
    let (gain, z) = (v.gain.unwrap(), v.z.unwrap());
    assert!((gain - (before - after) / before).abs() < 1e-12, "{gain}");
    assert!((z - t / s2.sqrt()).abs() < 1e-9, "{z}");
    for e in &ok {
        assert!((e.z - e.loss_gain / e.loss_se).abs() < 1e-9);
        assert!((e.gain - (1.0 - e.sse_after / e.sse_before)).abs() < 1e-12);
    }
    // Verified across the fleet, with a positive gain; single drives mostly not.
    assert!(v.verified, "{}", v.why);
    assert_eq!(v.reason, "verified_pooled_z");
    assert!(gain > 0.0 && z >= v.z_bar, "{gain} {z}");
    let alone_z = ok.iter().filter(|e| e.z >= v.z_bar).count();
    assert!(alone_z <= 12, "{alone_z} of 96 drives reach the bar alone");
    assert!(v.drives_verified_alone <= 2, "{}", v.drives_verified_alone);
    assert_eq!(d.best_edit.as_deref(), Some("col:load"));
    assert!(d.summary.contains("verified_pooled_z"), "{}", d.summary);
    // The drives' order does not change it.
    let mut again = suggesting("load", &cands);
    let mut rev = drives.clone();
    rev.reverse();
    pool_verifications(&mut again, &rev);
    assert_eq!(again, d);
    // Not a covariate's terms: the first candidate any drive refits is judged, not the best.
    let mut first = suggesting("load", &["bins:load", "col:load"]);
    first.verification.try_all = false;
    pool_verifications(&mut first, &drives);
    assert_eq!(first.verification.term.as_deref(), Some("bins:load"));
}

#[test]
fn an_edit_without_effect_is_not_verified_by_the_fleet() {
    // `temp` has no effect: refitted with each of its terms, the best one's fleet z stays
    // below the bar in every one of several fleets (under no effect its expectation is
    // negative: the refit's cost).
    for first in [200, 300, 400] {
        let fleet = load_fleet(first, 16, 400, 0.0);
        let cands = ["bins:temp", "col:temp", "lag:temp"];
        let mut d = suggesting("temp", &cands);
        pool_verifications(&mut d, &refits(&fleet, &cands));
        let v = &d.verification;
        assert!(!v.verified, "{}", v.why);
        assert_eq!(v.reason, "not_significant_pooled_z");
        assert_eq!(d.best_edit, None);
    }
    // A drive whose refit fails is named, not pooled; none left: no_drive_refitted.
    let fleet = load_fleet(500, 2, 300, 0.0);
    let mut d = suggesting("humidity", &["col:humidity"]);
    pool_verifications(&mut d, &refits(&fleet, &["col:humidity"]));
    let v = &d.verification;
    assert_eq!(
        (v.reason, v.failed.len(), v.drives),
        ("no_drive_refitted", 2, 0)
    );
    assert!(v.gain.is_none() && !v.verified);
}

#[test]
fn a_fleet_whose_model_lacks_nothing_verifies_nothing() {
    let fleet = load_fleet(600, 8, 400, 0.0);
    let (screens, config) = screens_of(&fleet);
    let mut d = pool(&screens, &config, &Default::default()).unwrap();
    assert!(d.features.iter().all(|f| !f.flagged), "{}", d.summary);
    assert_eq!(d.verification.reason, "nothing_flagged");
    assert_eq!(d.verification.term, None);
    // Nothing to verify: pooling refits changes nothing.
    let before = d.clone();
    pool_verifications(&mut d, &refits(&fleet, &["col:temp"]));
    assert_eq!(d, before);
    assert_eq!(d.best_edit, None);
}
