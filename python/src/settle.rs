//! `settle`, and the settle description a handoff uses: a preset or a plant file, with
//! settings overridden by name.

use crate::errors::{Failure, Kind, detached, fail};
use biasctl::SettleSpec;
use pyo3::prelude::*;
use std::path::Path;

/// The settle description named by `plant`: a plant TOML file when it ends in `.toml` or is a
/// file, else a preset; then `overrides` (a JSON object of `SettleSpec` settings) applied.
pub(crate) fn spec(plant: &str, overrides: Option<&str>) -> Result<SettleSpec, Failure> {
    let mut spec = if plant.ends_with(".toml") || Path::new(plant).is_file() {
        SettleSpec::from_toml_file(Path::new(plant)).map_err(fail(Kind::Settle))?
    } else {
        SettleSpec::preset(plant).map_err(fail(Kind::Settle))?
    };
    if let Some(o) = overrides {
        let over: serde_json::Map<String, serde_json::Value> = serde_json::from_str(o)
            .map_err(|e| Failure::new(Kind::Settle, format!("settings: {e}")))?;
        let mut value =
            serde_json::to_value(&spec).map_err(|e| Failure::new(Kind::Settle, e.to_string()))?;
        let fields = value
            .as_object_mut()
            .ok_or_else(|| Failure::new(Kind::Settle, "internal: the spec is no object"))?;
        for (k, v) in over {
            if !fields.contains_key(&k) {
                let mut known: Vec<&String> = fields.keys().collect();
                known.sort();
                return Err(Failure::new(
                    Kind::Settle,
                    format!(
                        "`{k}` is not a setting of the settle description (settings: {})",
                        known
                            .iter()
                            .map(|s| s.as_str())
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                ));
            }
            fields.insert(k, v);
        }
        spec = serde_json::from_value(value)
            .map_err(|e| Failure::new(Kind::Settle, format!("settings: {e}")))?;
    }
    Ok(spec)
}

/// `settle`: the report as `biasctl settle --json` prints it.
#[pyfunction]
#[pyo3(signature = (plant="paper1997", overrides=None))]
pub(crate) fn settle(py: Python<'_>, plant: &str, overrides: Option<String>) -> PyResult<String> {
    let plant = plant.to_string();
    detached(py, move || {
        let cfg = spec(&plant, overrides.as_deref())?
            .check()
            .map_err(fail(Kind::Settle))?;
        let report = biasctl::analyse(&cfg).map_err(fail(Kind::Settle))?;
        report.to_json().map_err(fail(Kind::Settle))
    })
}

/// The integrator start values of `predict --handoff` / `export c --handoff`.
pub(crate) fn start_values(plant: &str, delta_b: f64) -> Result<biasctl::StartValues, Failure> {
    let cfg = spec(plant, None)?.check().map_err(fail(Kind::Settle))?;
    biasctl::StartValues::new(&cfg, delta_b).map_err(fail(Kind::Settle))
}
