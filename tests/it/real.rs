//! Real measurements nobody on this project wrote (`../shared/data/real/`, see its README).
//! The data must be present: a missing file fails the test (CI has `../shared/` beside the clone).

use crate::common::{ok, real_data};

fn need(rel: &str) -> String {
    real_data(rel).unwrap_or_else(|| panic!("real data `{rel}` missing under ../shared/data/real"))
}

/// EMPS: `direction,col:velocity_m_s,col:accel_m_s2` plus the intercept is the benchmark's
/// IDIM-LS model with sign(velocity) replaced by the direction of the last position change.
/// Reference: Janot, Gautier, Brunot 2019, M = 95.1 kg, Fv = 203.5 N·s/m, Fc = 20.39 N,
/// offset = −3.16 N; each within 10 %.
#[test]
fn emps_recovers_the_published_idim_ls_parameters() {
    let data = need("emps/emps_estimation.csv");
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("m.json").display().to_string();
    ok(&[
        "fit",
        "--data",
        &data,
        "--track-col",
        "position_m",
        "--bias-col",
        "force_N",
        "--terms",
        "direction,col:velocity_m_s,col:accel_m_s2",
        "--out",
        &model,
    ]);
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&model).unwrap()).unwrap();
    let text = v.to_string();
    let param = |name: &str| -> f64 {
        let find = |node: &serde_json::Value| -> Option<f64> {
            node["terms"]
                .as_array()?
                .iter()
                .flat_map(|t| t["params"].as_array().cloned().unwrap_or_default())
                .find(|p| p["name"] == name)?["value"]
                .as_f64()
        };
        find(&v).unwrap_or_else(|| panic!("{name} not in {text}"))
    };
    for (name, published) in [
        ("col:accel_m_s2.slope", 95.1),
        ("col:velocity_m_s.slope", 203.5),
        ("direction.Fc", 20.39),
        ("intercept.c", -3.16),
    ] {
        let ours = param(name);
        assert!(
            ((ours - published) / published).abs() < 0.10,
            "{name}: ours {ours}, published {published}"
        );
    }
}

/// EMPS with position-direction only: the acceleration column (M·a) must rank first.
#[test]
fn emps_diagnose_points_at_acceleration() {
    let data = need("emps/emps_estimation.csv");
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("m.json").display().to_string();
    ok(&[
        "fit",
        "--data",
        &data,
        "--track-col",
        "position_m",
        "--bias-col",
        "force_N",
        "--model",
        "position-direction",
        "--out",
        &model,
    ]);
    let j = ok(&[
        "diagnose",
        "--model",
        &model,
        "--data",
        &data,
        "--track-col",
        "position_m",
        "--bias-col",
        "force_N",
        "--json",
        "--permutations",
        "99",
    ]);
    let v: serde_json::Value = serde_json::from_str(&j).unwrap();
    assert_eq!(v["features"][0]["name"], "accel_m_s2", "{}", v["summary"]);
}

/// Pneumatic seal: force ≈ pressure × piston area, so in a log that mixes 1–7 bar the logged
/// `pressure_bar` must rank first.
#[test]
fn pneumatic_diagnose_ranks_pressure_first() {
    let data = need("pneumatic/oring257_1-7bar.csv");
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("m.json").display().to_string();
    ok(&[
        "fit",
        "--data",
        &data,
        "--track-col",
        "position_mm",
        "--bias-col",
        "force_N",
        "--model",
        "position-direction",
        "--out",
        &model,
    ]);
    let j = ok(&[
        "diagnose",
        "--model",
        &model,
        "--data",
        &data,
        "--track-col",
        "position_mm",
        "--bias-col",
        "force_N",
        "--json",
        "--permutations",
        "99",
    ]);
    let v: serde_json::Value = serde_json::from_str(&j).unwrap();
    assert_eq!(v["features"][0]["name"], "pressure_bar", "{}", v["summary"]);
}

/// EMPS with position-direction only: the IDIM-LS model (Janot, Gautier, Brunot 2019) says the
/// missing terms are M·a and Fv·v, so the two top features must be `accel_m_s2` and
/// `velocity_m_s` (either order).
#[test]
#[ignore = "known failure: after accel_m_s2, since_reversal × direction explains 8.7 % beyond it, velocity_m_s 6.3 % (not a near-tie), so since_reversal ranks second"]
fn emps_diagnose_points_at_acceleration_and_velocity() {
    let data = need("emps/emps_estimation.csv");
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("m.json").display().to_string();
    ok(&[
        "fit",
        "--data",
        &data,
        "--track-col",
        "position_m",
        "--bias-col",
        "force_N",
        "--model",
        "position-direction",
        "--out",
        &model,
    ]);
    let j = ok(&[
        "diagnose",
        "--model",
        &model,
        "--data",
        &data,
        "--track-col",
        "position_m",
        "--bias-col",
        "force_N",
        "--json",
        "--permutations",
        "99",
    ]);
    let v: serde_json::Value = serde_json::from_str(&j).unwrap();
    let mut top: Vec<&str> = (0..2)
        .map(|i| v["features"][i]["name"].as_str().unwrap_or(""))
        .collect();
    top.sort_unstable();
    assert_eq!(top, ["accel_m_s2", "velocity_m_s"], "{}", v["summary"]);
}
