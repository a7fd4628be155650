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
    let spec = ModelSpec::parse("poly2,direction").unwrap();
    let opts = FitOptions::default().check().unwrap();
    let config = DiagnoseConfig {
        permutations: 99,
        ..DiagnoseConfig::default()
    }
    .check()
    .unwrap();
    let s = seeds
        .iter()
        .map(|&seed| screen_drive(&format!("d{seed}"), &simulated(seed), &spec, &opts, &config))
        .collect();
    (s, config)
}

#[test]
fn a_pool_of_one_drive_is_that_drives_own_screen() {
    let (s, config) = screens(&[3]);
    let own = s[0].screen.as_ref().unwrap();
    let d = pool(&s, &config).unwrap();
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
    let d = pool(&s, &config).unwrap();
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
    assert_eq!(pool(&s, &config).unwrap(), d);
}
