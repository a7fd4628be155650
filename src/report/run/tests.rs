//! The runs computed without HTML, against independent recomputations.

use super::*;
use crate::control::settle::{SettleSpec, analyse};
use crate::model::preset;

/// The computation alone, no HTML: the demo run on 300 seeks holds what the report shows,
/// and its numbers agree with independent recomputations.
#[test]
fn demo_run_computes_every_part_without_html() {
    let dir = tempfile::tempdir().unwrap();
    let run = compute_demo(
        dir.path(),
        &StoryOptions::quick(5).check().unwrap(),
        &mut |_| {},
    )
    .unwrap();
    assert_eq!(run.tables.len(), 7);
    assert_eq!(run.scored.len(), STORY_MODELS.len());
    // Reference: every score is the std of measured − predicted of a fresh replay of the
    // saved model over random.csv (the batch path, recomputed here).
    for s in &run.scored {
        let p = s.model.predict_log(&run.random).unwrap();
        let std = crate::numeric::stats::std_dev(&p.residual).unwrap();
        assert!(
            (s.score.std - std).abs() <= 1e-12 * std.max(1.0),
            "{}",
            s.label
        );
        assert_eq!(s.scored_on, "random.csv");
    }
    assert_eq!(run.scored[0].trained_on, "table1.csv");
    // The ladder's last rung is the calibration model: same terms, same test error std as
    // its own fit and score above (reference: the scored calibration model).
    let last = run.ladder.steps.last().unwrap();
    assert_eq!(last.terms.join(","), preset::CALIBRATION);
    assert!((last.std - run.scored[1].score.std).abs() < 1e-9 * last.std.max(1.0));
    // Discover ran on the demo's data, starting at position-direction.
    let d = run.discovery.as_ref().unwrap();
    assert!(d.start_std.is_finite() && !d.stopped_because.is_empty());
    // Every file listed exists in the logs folder.
    for (f, _) in &run.files {
        assert!(dir.path().join(f).is_file(), "{f}");
    }
    // The link's Δb is each model's test error std.
    for ((l, db, _), s) in run.settle.link.iter().zip(&run.scored) {
        assert_eq!(l, &s.label);
        assert!((db - s.score.std).abs() < 1e-15 * db.max(1.0));
    }
}

/// Reference: the simulated responses of the settle analysis. The entry sample of a start
/// value into the running bounds is its settle time, so the paper's choice and zero
/// feedforward enter where their simulated responses settle.
#[test]
fn paper_robust_why_matches_the_simulated_settle_times() {
    let cfg = SettleSpec::preset("paper1997").unwrap().check().unwrap();
    let r = analyse(&cfg).unwrap();
    let why = PaperRobustWhy::of(&r).unwrap();
    let p = r.paper_robust.as_ref().unwrap();
    assert_eq!(why.paper_entry_ms, p.settle_ms);
    assert_eq!(why.zero_entry_ms, r.zero_ff_settle_ms);
    let [lo, hi] = why.bounds_at_k_min;
    assert!((why.ff - 0.5 * (lo + hi)).abs() < 1e-9 * (hi - lo).abs().max(1.0));
    assert!(why.k_min_ms > 0.0);
}

/// The flagship demo's discovery does not contradict its own ladder and diagnosis. Reference:
/// the ladder (independent refits, calibration run → random run) and the diagnosis of the
/// position-direction residual on the random run, both computed in the same run: beyond
/// position-direction (discover's start) the ladder's largest drop is the rung that adds
/// `seek`, and the diagnosis ranks a feature of the seek
/// history first. So discover — position-direction, trained on a second random run, scored on
/// the random run — must verify an edit, its first edit must come from the seek history
/// (seek length, reversals: `seek`, `play`, `dahl`), and the model it ends with must predict
/// the random run better than the ladder's position-direction rung.
#[test]
fn the_demo_discovery_finds_what_its_ladder_shows() {
    let dir = tempfile::tempdir().unwrap();
    let run = compute_demo(
        dir.path(),
        &StoryOptions::default().check().unwrap(),
        &mut |_| {},
    )
    .unwrap();
    let rungs = &run.ladder.steps;
    let drop = |i: usize| rungs[i - 1].std - rungs[i].std;
    let start = rungs
        .iter()
        .position(|s| s.terms.join(",") == preset::POSITION_DIRECTION)
        .unwrap();
    let biggest = (start + 1..rungs.len())
        .max_by(|&a, &b| drop(a).total_cmp(&drop(b)))
        .unwrap();
    assert_eq!(rungs[biggest].added_since(&rungs[biggest - 1]), ["seek"]);
    let history = [
        "seek_length",
        "seek_abs",
        "since_reversal",
        "direction_change",
    ];
    let top = &run.diagnosis.diagnosis.features[0].name;
    assert!(
        history.contains(&top.as_str()),
        "diagnosis leads with {top}"
    );
    // The page's feature table names each feature's verdict by its rule.
    let table = crate::report::sections::diagnosis::diagnosis_table(&run.diagnosis.diagnosis, 6);
    let col = table.header.iter().position(|h| h == "verdict").unwrap();
    for (row, f) in table.rows.iter().zip(&run.diagnosis.diagnosis.features) {
        assert!(
            matches!(&row[col], crate::report::Cell::Text(t) if t == f.reason.words()),
            "{}: {:?}",
            f.name,
            row[col]
        );
    }
    assert!(matches!(&table.rows[0][col], crate::report::Cell::Text(t) if t == "flagged"));
    let d = run.discovery.as_ref().unwrap();
    let text = d.to_string();
    let first = d
        .steps
        .first()
        .unwrap_or_else(|| panic!("no edit verified:\n{text}"));
    assert!(history.contains(&first.feature.as_str()), "{text}");
    assert!(
        ["seek", "play", "dahl"]
            .iter()
            .any(|t| first.edit.starts_with(&format!("add {t}"))),
        "{text}"
    );
    // The page says so beside the ladder.
    let beside = crate::report::story::discovery_beside_ladder(&run).unwrap();
    assert!(
        beside.contains(&format!("`{}`", first.edit))
            && beside.contains("Both are terms of the seek history"),
        "{beside}"
    );
    let last = d.steps.last().unwrap();
    assert!(
        last.std_after < rungs[start].std,
        "{text}\nladder: {}",
        rungs[start].std
    );
    assert!(
        run.files
            .iter()
            .any(|(f, _)| f == &format!("{DISCOVER_TRAIN}.csv")),
        "{:?}",
        run.files
    );
}
