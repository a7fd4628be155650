//! Named models: `position-direction` = poly2+direction (the industry practice of 1997),
//! `calibration` = poly2+direction+seek+memory+drift (eq. 1), `dahl` = poly2+dahl (eqs. 8–9).
//! This is the only place their term lists are spelled; the report, the plots and the CLI
//! take them from here ([`PRESET_LIST`], [`CALIBRATION_TERMS`], [`RICH_DAHL`]).

use super::{ModelSpec, SpecError};

/// Terms of `position-direction`.
pub(crate) const POSITION_DIRECTION: &str = "poly2,direction";
/// Terms of `calibration` (eq. 1), as one list.
pub const CALIBRATION: &str = "poly2,direction,seek,memory,drift";
/// Terms of `calibration`, one by one, in order (the ladder adds them one at a time).
pub(crate) const CALIBRATION_TERMS: [&str; 5] = ["poly2", "direction", "seek", "memory", "drift"];
/// Terms of `dahl`.
pub(crate) const DAHL: &str = "poly2,dahl";
/// Not a preset: the richer state-space friction model (four Dahl elements) the report fits
/// beside the presets.
pub(crate) const RICH_DAHL: &str = "poly2,dahl:4";

/// Every preset: (name, term list).
pub(crate) const PRESET_LIST: [(&str, &str); 3] = [
    ("position-direction", POSITION_DIRECTION),
    ("calibration", CALIBRATION),
    ("dahl", DAHL),
];

/// Preset names.
pub(crate) const PRESETS: [&str; 3] = [PRESET_LIST[0].0, PRESET_LIST[1].0, PRESET_LIST[2].0];

/// The term list of preset `name`.
pub fn preset_terms(name: &str) -> Option<&'static str> {
    PRESET_LIST
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, terms)| *terms)
}

/// The spec of preset `name`.
pub(crate) fn preset(name: &str) -> Result<ModelSpec, SpecError> {
    let list = preset_terms(name).ok_or_else(|| SpecError::UnknownPreset { name: name.into() })?;
    ModelSpec::parse(list)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn calibration_list_and_terms_agree_and_every_list_parses() {
        // Reference: the two spellings of eq. 1 are the same list; every list is a valid spec.
        assert_eq!(CALIBRATION_TERMS.join(","), CALIBRATION);
        for (name, terms) in PRESET_LIST {
            assert_eq!(preset(name).unwrap().to_string(), terms);
        }
        assert_eq!(ModelSpec::parse(RICH_DAHL).unwrap().to_string(), RICH_DAHL);
        assert!(preset_terms("nope").is_none());
    }
}
