//! Checked settings (unchecked → `check()` → checked, as linfa's `ParamGuard`) of the story
//! (`report`/`demo`), the ladder and the diagnose plot: a bad value is refused before anything
//! runs, with exit 2, a message naming the flag (the CLI's field → flag table) and nothing
//! written. Reference: the documented range of each setting.

use crate::common::{biasctl, fails_with, ok};
use biasctl::plot::views::PanelOptions;
use biasctl::{StoryOptions, ladder_terms};

#[test]
fn report_refuses_seeks_out_of_range_naming_the_flag() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("r");
    let out_s = out.display().to_string();
    for seeks in ["5", "1000001"] {
        let e = fails_with(
            &["report", "--out", &out_s, "--seeks", seeks],
            &[&format!("--seeks {seeks}: give "), "random seeks"],
        );
        assert!(!e.contains("StoryOptions"), "library name leaked: {e}");
        assert!(!out.exists(), "report wrote {out_s} for --seeks {seeks}");
    }
    let e = fails_with(
        &["demo", "--out", &out_s, "--seeks", "0"],
        &["--seeks 0: give "],
    );
    assert!(!e.contains("StoryOptions"), "{e}");
    assert!(!out.exists());
}

#[test]
fn ladder_refuses_an_empty_term_naming_the_flag() {
    // The term list is checked before either log is read: the logs need not exist.
    let e = fails_with(
        &[
            "ladder",
            "--data",
            "none.csv",
            "--test",
            "none.csv",
            "--terms",
            "poly2,,seek",
        ],
        &["--terms: term list `poly2,,seek`: term 2 is empty"],
    );
    assert!(!e.contains("LadderTerms"), "{e}");
    assert!(
        !e.contains("none.csv"),
        "logs read before the terms were checked: {e}"
    );
}

#[test]
fn plot_refuses_top_zero_naming_the_flag() {
    let dir = tempfile::tempdir().unwrap();
    let svg = dir.path().join("d.svg");
    let svg_s = svg.display().to_string();
    let e = fails_with(
        &[
            "plot", "diagnose", "--out", &svg_s, "--data", "none.csv", "--model", "poly2", "--top",
            "0",
        ],
        &["--top 0: give at least 1"],
    );
    assert!(!e.contains("PanelOptions"), "{e}");
    assert!(!svg.exists());
    // The same flag on a plot that has a valid value draws as before (checked default).
    let r = biasctl(&["plot", "bounds", "--out", &svg_s, "--top", "1"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
}

#[test]
fn library_checks_name_the_setting() {
    // Library-only settings (no flag): the error names the field as the library knows it.
    let cases = [
        (
            StoryOptions {
                permutations: 0,
                ..StoryOptions::default()
            },
            "StoryOptions::permutations 0: ",
        ),
        (
            StoryOptions {
                settle_preset: "nope".into(),
                ..StoryOptions::default()
            },
            "StoryOptions::settle_preset ",
        ),
        (
            StoryOptions {
                random_seeks: 1,
                ..StoryOptions::default()
            },
            "StoryOptions::random_seeks 1: ",
        ),
    ];
    for (opts, want) in cases {
        let e = opts.check().unwrap_err();
        assert!(e.to_string().starts_with(want), "{e}");
    }
    assert!(StoryOptions::default().check().is_ok());
    assert!(StoryOptions::quick(3).check().is_ok());

    let e = PanelOptions { top: 0 }.check().unwrap_err();
    assert_eq!(e.to_string(), "PanelOptions::top 0: give at least 1");
    assert_eq!(PanelOptions { top: 1 }.check().unwrap().top, 1);

    let e = ladder_terms(" ,poly2").unwrap_err();
    assert!(
        e.to_string()
            .starts_with("LadderTerms::terms: term list ` ,poly2`: term 1 is empty"),
        "{e}"
    );
    assert_eq!(&*ladder_terms("poly2, seek").unwrap(), ["poly2", "seek"]);
}

/// Reference: the term registry (`biasctl::builtin_names`, what a spec error lists). `fit
/// --help` lists every built-in term's syntax, so a new term cannot be missing from the help
/// (its text was written by hand and had fallen eight terms behind).
#[test]
fn fit_help_lists_every_built_in_term() {
    let help = ok(&["fit", "--help"]);
    let flat = help.split_whitespace().collect::<Vec<_>>().join(" ");
    for syntax in biasctl::builtin_names().split(", ") {
        assert!(
            flat.contains(syntax),
            "`{syntax}` missing from fit --help:\n{help}"
        );
    }
}
