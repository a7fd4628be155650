//! Named models: `position-direction` = poly2+direction (the industry practice of 1997),
//! `calibration` = poly2+direction+seek+memory+drift (eq. 1), `dahl` = poly2+dahl (eqs. 8–9).

use super::{ModelSpec, SpecError};

/// Preset names.
pub const PRESETS: [&str; 3] = ["position-direction", "calibration", "dahl"];

/// The term list of preset `name`.
pub fn preset_terms(name: &str) -> Option<&'static str> {
    match name {
        "position-direction" => Some("poly2,direction"),
        "calibration" => Some("poly2,direction,seek,memory,drift"),
        "dahl" => Some("poly2,dahl"),
        _ => None,
    }
}

/// The spec of preset `name`.
pub fn preset(name: &str) -> Result<ModelSpec, SpecError> {
    let list = preset_terms(name).ok_or_else(|| SpecError::UnknownPreset { name: name.into() })?;
    ModelSpec::parse(list)
}
