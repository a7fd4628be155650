//! `biasctl export c`: the generated C, compiled with the system C compiler, replays a held-out
//! log to the same predictions as `biasctl predict` (the reference), in double and in float.

use crate::common::{fails_with, ok, write};
use crate::predict::{column, edit_log, logs};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// The system C compiler: `$CC`, else the first of cc, gcc, clang that runs.
fn c_compiler() -> String {
    let candidates: Vec<String> = std::env::var("CC")
        .ok()
        .into_iter()
        .chain(["cc", "gcc", "clang"].map(String::from))
        .collect();
    for cc in &candidates {
        let found = Command::new(cc)
            .arg("--version")
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success());
        if found {
            return cc.clone();
        }
    }
    panic!(
        "no C compiler found (tried $CC, cc, gcc, clang): the export test compiles the generated C \
         and needs one; install one (CI has one)"
    );
}

/// Starts `cc -std=c99 -O2 DIR/*.c -lm -o DIR/replay`, with warnings as errors.
fn compile(cc: &str, dir: &Path) -> std::process::Child {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "c"))
        .collect();
    files.sort();
    assert_eq!(files.len(), 2, "{files:?}");
    Command::new(cc)
        .args([
            "-std=c99",
            "-O2",
            "-Wall",
            "-Wextra",
            "-pedantic",
            "-Werror",
        ])
        .args(&files)
        .args(["-lm", "-o"])
        .arg(dir.join("replay"))
        .stderr(Stdio::piped())
        .spawn()
        .expect("run the C compiler")
}

/// Runs DIR/replay with `log` on stdin; returns its stdout lines.
fn replay(dir: &Path, log: &str) -> Vec<String> {
    let out = Command::new(dir.join("replay"))
        .stdin(std::fs::File::open(log).unwrap())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "replay failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(str::to_string)
        .collect()
}

/// Largest |c − r| / max(|r|, 1) over the rows (bias in counts: below 1 count the error is
/// taken as absolute).
fn max_rel(c: &[f64], r: &[f64]) -> f64 {
    assert_eq!(c.len(), r.len());
    c.iter()
        .zip(r)
        .map(|(a, b)| (a - b).abs() / b.abs().max(1.0))
        .fold(0.0, f64::max)
}

fn numbers(cells: &[String]) -> Vec<f64> {
    cells.iter().map(|c| c.parse().unwrap()).collect()
}

#[test]
fn exported_c_replays_like_predict_for_every_term_kind() {
    let cc = c_compiler();
    let dir = tempfile::tempdir().unwrap();
    let (train, test) = logs(dir.path());
    // The held-out log: measured history, then a plan (drift must hold over it in C too).
    let text = std::fs::read_to_string(&test).unwrap();
    let held_out = write(
        dir.path(),
        "held_out.csv",
        &edit_log(&text, false, 300..400),
    );
    let models: [(&str, &str); 9] = [
        ("pd", "--model=position-direction"),
        ("cal", "--model=calibration"),
        ("dahl", "--model=dahl"),
        (
            "all",
            "--terms=table:250,direction,seek,memory,drift,dahl:4,col:temp_c,bins:dwell_s,dbins:rest_distance_id",
        ),
        (
            "icpt",
            "--terms=direction,dahl:3,bins:since_reversal,bins:temp_c:3",
        ),
        // Velocity friction: derived velocity (seek over dwell) and a column.
        ("fric", "--terms=poly2,viscous,stribeck,viscous:temp_c"),
        // A localized defect (the fitted Gaussian's centre and width).
        ("bump", "--terms=poly2,direction,bump"),
        // A threshold in a covariate (the fitted step's height and threshold).
        ("step", "--terms=poly2,direction,step:temp_c"),
        // Hysteresis with reversal memory (the relay staircase, its demagnetised start).
        ("preisach", "--terms=poly2,preisach:6"),
    ];
    let mut jobs = Vec::new();
    for (name, spec) in models {
        let model = dir
            .path()
            .join(format!("{name}.json"))
            .display()
            .to_string();
        ok(&["fit", "--data", &train, spec, "--out", &model]);
        let pred = dir
            .path()
            .join(format!("{name}.pred.csv"))
            .display()
            .to_string();
        let handoff = name == "cal";
        let mut args = vec![
            "predict", "--model", &model, "--data", &held_out, "--out", &pred,
        ];
        if handoff {
            args.extend(["--handoff", "paper1997"]);
        }
        ok(&args);
        let reference = std::fs::read_to_string(&pred).unwrap();
        for float32 in [false, true] {
            let out = dir.path().join(format!("{name}_{float32}"));
            let out_s = out.display().to_string();
            let mut args = vec!["export", "c", "--model", &model, "--out", &out_s];
            if float32 {
                args.push("--float32");
            }
            if handoff {
                args.extend(["--handoff", "paper1997"]);
            }
            ok(&args);
            let source = std::fs::read_to_string(out.join("bias_model.c")).unwrap();
            assert!(!source.contains("alloc("), "allocation in {name}");
            jobs.push((
                name,
                float32,
                handoff,
                out.clone(),
                reference.clone(),
                compile(&cc, &out),
            ));
        }
    }
    let mut figures = Vec::new();
    for (name, float32, handoff, out, reference, child) in jobs {
        let o = child.wait_with_output().unwrap();
        assert!(
            o.status.success(),
            "{name} (float32 {float32}): the C does not compile:\n{}",
            String::from_utf8_lossy(&o.stderr)
        );
        let lines = replay(&out, &held_out);
        let want = numbers(&column(&reference, "predicted"));
        assert_eq!(lines.len(), want.len(), "{name}: one line per row");
        let cells: Vec<Vec<String>> = lines
            .iter()
            .map(|l| l.split(',').map(str::to_string).collect())
            .collect();
        let got: Vec<f64> = cells.iter().map(|c| c[0].parse().unwrap()).collect();
        let err = max_rel(&got, &want);
        let tol = if float32 { 1e-4 } else { 1e-9 };
        figures.push(format!("{name} float32={float32}: max rel error {err:.2e}"));
        assert!(
            err <= tol,
            "{name} (float32 {float32}): max relative error {err:e} > {tol:e}"
        );
        if handoff {
            let z_want = numbers(&column(&reference, "integrator_start"));
            let z_got: Vec<f64> = cells.iter().map(|c| c[1].parse().unwrap()).collect();
            let err = max_rel(&z_got, &z_want);
            figures.push(format!(
                "{name} float32={float32}: integrator_start max rel error {err:.2e}"
            ));
            assert!(
                err <= tol,
                "{name} integrator_start (float32 {float32}): {err:e} > {tol:e}"
            );
        }
    }
    eprintln!("{}", figures.join("\n"));
}

#[test]
fn export_refuses_what_it_cannot_write() {
    let dir = tempfile::tempdir().unwrap();
    let file = write(dir.path(), "file.txt", "x");
    let missing = dir.path().join("nope.json").display().to_string();
    fails_with(
        &["export", "c", "--model", &missing, "--out", &file],
        &["nope.json"],
    );
    let csv = "time_s,track,bias\n0,100,1\n1,200,3\n2,150,2\n3,120,1.5\n4,180,2.5\n5,110,1.2\n";
    let log = write(dir.path(), "log.csv", csv);
    let model = dir.path().join("m.json").display().to_string();
    ok(&["fit", "--data", &log, "--terms", "poly2", "--out", &model]);
    fails_with(
        &["export", "c", "--model", &model, "--out", &file],
        &["file.txt", "not a folder"],
    );
}

/// A user term that does not describe itself in C is refused by name; one that does is exported.
#[test]
fn user_terms_export_themselves_or_are_refused_by_name() {
    use biasctl::{COptions, ExportError, c_source, export::CContext, export::CTerm};
    use biasctl::{CheckedFitOptions, FitData, FitError, fit};
    use biasctl::{ModelError, ModelSpec};
    use biasctl::{Term, TermSpec, model::Seek, model::TermState};
    use std::sync::Arc;

    /// Bias ∝ seek length², counts per track²; `exports` says whether it writes C.
    #[derive(Debug, Clone, Copy)]
    struct Sq {
        exports: bool,
    }
    impl TermSpec for Sq {
        fn name(&self) -> String {
            "seek_squared".into()
        }
        fn prepare(&self, _d: &FitData<'_>) -> Result<Arc<dyn Term>, FitError> {
            Ok(Arc::new(*self))
        }
    }
    impl Term for Sq {
        fn name(&self) -> String {
            "seek_squared".into()
        }
        fn param_names(&self) -> Vec<String> {
            vec!["k".into()]
        }
        fn start(&self, _c: &[String]) -> Result<Box<dyn TermState>, ModelError> {
            Ok(Box::new(*self))
        }
        fn export_c(&self, _ctx: &CContext) -> Option<CTerm> {
            self.exports.then(|| {
                let mut t = CTerm::default();
                t.basis = "b[0] = f->seek_length * f->seek_length;".into();
                t
            })
        }
    }
    impl TermState for Sq {
        fn basis(&self, s: &Seek<'_>, out: &mut [f64]) {
            out[0] = s.features.seek_length.powi(2);
        }
        fn update(&mut self, _s: &Seek<'_>, _r: Option<f64>) {}
        fn clone_box(&self) -> Box<dyn TermState> {
            Box::new(*self)
        }
    }
    let csv = "time_s,track,bias\n0,100,3\n1,130,12\n2,90,19\n3,150,39\n4,120,12\n5,80,19\n";
    let log = biasctl::Log::from_reader("x.csv", csv.as_bytes(), &Default::default()).unwrap();
    for exports in [false, true] {
        let spec = ModelSpec::parse("poly2")
            .unwrap()
            .with_term(Arc::new(Sq { exports }));
        let model = fit(&spec, &log, &CheckedFitOptions::default()).unwrap();
        match c_source(&model, &COptions::default()) {
            Err(ExportError::NotExportable { term }) => {
                assert!(!exports);
                assert_eq!(term, "seek_squared");
            }
            Ok(src) => {
                assert!(exports);
                assert!(src.source.contains("f->seek_length * f->seek_length"));
            }
            Err(e) => panic!("{e}"),
        }
    }
}
