//! Names of the settings a library error can blame.
//!
//! A library error that rejects a setting carries a [`Field`]: the setting as the library knows
//! it, printed as `Type::field` ([`SettleSpec::step_um`](crate::control::settle::SettleSpec),
//! `ColumnMap::bias`, …). The library never names a command-line flag; the `biasctl` binary owns
//! the one table field → flag and renders each field as its flag in the messages it prints
//! (`SequenceOptions::span 0: must be > 0` reads `--span 0: must be > 0` there).

use std::fmt;

/// A setting of a library configuration type, named in errors. Its `Display` is
/// [`Field::name`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Field {
    /// [`ColumnMap::time`](crate::log::ColumnMap::time): the time column's name.
    TimeColumn,
    /// [`ColumnMap::track`](crate::log::ColumnMap::track): the position column's name.
    TrackColumn,
    /// [`ColumnMap::bias`](crate::log::ColumnMap::bias): the bias column's name.
    BiasColumn,
    /// The explicit bias unit label of [`Units::resolve`](crate::log::Units::resolve).
    BiasUnit,
    /// The explicit position unit label of [`Units::resolve`](crate::log::Units::resolve).
    PositionUnit,
    /// The sequence name given to [`SimConfig::new`](crate::sim::SimConfig::new).
    Sequence,
    /// The effects switched off in [`SimConfig::new`](crate::sim::SimConfig::new).
    Disabled,
    /// [`SequenceOptions::n`](crate::sim::SequenceOptions::n): random seeks.
    SeekCount,
    /// [`SequenceOptions::span`](crate::sim::SequenceOptions::span): random range, tracks.
    Span,
    /// [`SequenceOptions::center`](crate::sim::SequenceOptions::center): centre track.
    Center,
    /// [`SequenceOptions::dwell_min_s`](crate::sim::SequenceOptions::dwell_min_s), s.
    DwellMin,
    /// [`SequenceOptions::dwell_max_s`](crate::sim::SequenceOptions::dwell_max_s), s.
    DwellMax,
    /// [`SequenceOptions::script`](crate::sim::SequenceOptions::script): the script file.
    Script,
    /// [`SettleSpec::step_um`](crate::control::settle::SettleSpec::step_um), µm.
    StepUm,
    /// [`SettleSpec::window_um`](crate::control::settle::SettleSpec::window_um), µm.
    WindowUm,
    /// [`SettleSpec::bias`](crate::control::settle::SettleSpec::bias), counts.
    Bias,
    /// [`SettleSpec::bias_uncertainty`](crate::control::settle::SettleSpec::bias_uncertainty),
    /// counts (for a model, its residual std).
    BiasUncertainty,
    /// [`SettleSpec::horizon`](crate::control::settle::SettleSpec::horizon), samples.
    Horizon,
    /// [`SettleSpec::hold`](crate::control::settle::SettleSpec::hold), samples.
    Hold,
    /// [`FitOptions::rank_tolerance`](crate::fit::FitOptions::rank_tolerance).
    RankTolerance,
    /// [`FitOptions::grid`](crate::fit::FitOptions::grid).
    Grid,
    /// [`FitOptions::refine`](crate::fit::FitOptions::refine).
    Refine,
    /// [`DiagnoseConfig::folds`](crate::diagnose::DiagnoseConfig::folds).
    Folds,
    /// [`DiagnoseConfig::block_len`](crate::diagnose::DiagnoseConfig::block_len).
    BlockLen,
    /// [`DiagnoseConfig::alpha`](crate::diagnose::DiagnoseConfig::alpha).
    Alpha,
    /// [`DiagnoseConfig::permutations`](crate::diagnose::DiagnoseConfig::permutations).
    Permutations,
    /// [`DiagnoseConfig::max_bins`](crate::diagnose::DiagnoseConfig::max_bins).
    MaxBins,
    /// [`DiagnoseConfig::min_bin_rows`](crate::diagnose::DiagnoseConfig::min_bin_rows).
    MinBinRows,
    /// [`DiagnoseConfig::max_discrete`](crate::diagnose::DiagnoseConfig::max_discrete).
    MaxDiscrete,
    /// [`DiagnoseConfig::ljung_box_lags`](crate::diagnose::DiagnoseConfig::ljung_box_lags).
    LjungBoxLags,
    /// [`DiagnoseConfig::null_block`](crate::diagnose::DiagnoseConfig::null_block).
    NullBlock,
    /// [`DiagnoseConfig::min_effect`](crate::diagnose::DiagnoseConfig::min_effect).
    MinEffect,
    /// [`VerifyConfig::folds`](crate::select::VerifyConfig::folds).
    VerifyFolds,
    /// [`VerifyConfig::candidates`](crate::select::VerifyConfig::candidates).
    VerifyCandidates,
    /// [`VerifyConfig::min_z`](crate::select::VerifyConfig::min_z).
    MinZ,
    /// [`DiscoverConfig::max_steps`](crate::select::DiscoverConfig::max_steps).
    MaxSteps,
    /// [`StoryOptions::random_seeks`](crate::StoryOptions::random_seeks).
    RandomSeeks,
    /// [`StoryOptions::permutations`](crate::StoryOptions::permutations).
    StoryPermutations,
    /// [`StoryOptions::settle_preset`](crate::StoryOptions::settle_preset).
    SettlePreset,
    /// The term list given to [`ladder_terms`](crate::ladder_terms).
    LadderTerms,
    /// [`PanelOptions::top`](crate::plot::views::PanelOptions::top).
    PanelTop,
    /// The robust-z threshold of [`fleet::outliers`](crate::fleet::outliers).
    OutlierThreshold,
}

impl Field {
    /// Every field, for tables that must cover them all (the CLI's field → flag table).
    pub const ALL: [Field; 42] = [
        Field::TimeColumn,
        Field::TrackColumn,
        Field::BiasColumn,
        Field::BiasUnit,
        Field::PositionUnit,
        Field::Sequence,
        Field::Disabled,
        Field::SeekCount,
        Field::Span,
        Field::Center,
        Field::DwellMin,
        Field::DwellMax,
        Field::Script,
        Field::StepUm,
        Field::WindowUm,
        Field::Bias,
        Field::BiasUncertainty,
        Field::Horizon,
        Field::Hold,
        Field::RankTolerance,
        Field::Grid,
        Field::Refine,
        Field::Folds,
        Field::BlockLen,
        Field::Alpha,
        Field::Permutations,
        Field::MaxBins,
        Field::MinBinRows,
        Field::MaxDiscrete,
        Field::LjungBoxLags,
        Field::NullBlock,
        Field::MinEffect,
        Field::VerifyFolds,
        Field::VerifyCandidates,
        Field::MinZ,
        Field::MaxSteps,
        Field::RandomSeeks,
        Field::StoryPermutations,
        Field::SettlePreset,
        Field::LadderTerms,
        Field::PanelTop,
        Field::OutlierThreshold,
    ];

    /// The setting as `Type::field` (`Units::bias` and `SimConfig::…` for arguments of
    /// [`Units::resolve`](crate::log::Units::resolve) and
    /// [`SimConfig::new`](crate::sim::SimConfig::new)). Unique; one name may begin another
    /// (`SettleSpec::bias`, `SettleSpec::bias_uncertainty`), so a message is searched for whole
    /// names ([`Field::find_in`]).
    pub const fn name(self) -> &'static str {
        match self {
            Field::TimeColumn => "ColumnMap::time",
            Field::TrackColumn => "ColumnMap::track",
            Field::BiasColumn => "ColumnMap::bias",
            Field::BiasUnit => "Units::bias",
            Field::PositionUnit => "Units::position",
            Field::Sequence => "SimConfig::sequence",
            Field::Disabled => "SimConfig::disabled",
            Field::SeekCount => "SequenceOptions::n",
            Field::Span => "SequenceOptions::span",
            Field::Center => "SequenceOptions::center",
            Field::DwellMin => "SequenceOptions::dwell_min_s",
            Field::DwellMax => "SequenceOptions::dwell_max_s",
            Field::Script => "SequenceOptions::script",
            Field::StepUm => "SettleSpec::step_um",
            Field::WindowUm => "SettleSpec::window_um",
            Field::Bias => "SettleSpec::bias",
            Field::BiasUncertainty => "SettleSpec::bias_uncertainty",
            Field::Horizon => "SettleSpec::horizon",
            Field::Hold => "SettleSpec::hold",
            Field::RankTolerance => "FitOptions::rank_tolerance",
            Field::Grid => "FitOptions::grid",
            Field::Refine => "FitOptions::refine",
            Field::Folds => "DiagnoseConfig::folds",
            Field::BlockLen => "DiagnoseConfig::block_len",
            Field::Alpha => "DiagnoseConfig::alpha",
            Field::Permutations => "DiagnoseConfig::permutations",
            Field::MaxBins => "DiagnoseConfig::max_bins",
            Field::MinBinRows => "DiagnoseConfig::min_bin_rows",
            Field::MaxDiscrete => "DiagnoseConfig::max_discrete",
            Field::LjungBoxLags => "DiagnoseConfig::ljung_box_lags",
            Field::NullBlock => "DiagnoseConfig::null_block",
            Field::MinEffect => "DiagnoseConfig::min_effect",
            Field::VerifyFolds => "VerifyConfig::folds",
            Field::VerifyCandidates => "VerifyConfig::candidates",
            Field::MinZ => "VerifyConfig::min_z",
            Field::MaxSteps => "DiscoverConfig::max_steps",
            Field::RandomSeeks => "StoryOptions::random_seeks",
            Field::StoryPermutations => "StoryOptions::permutations",
            Field::SettlePreset => "StoryOptions::settle_preset",
            Field::LadderTerms => "LadderTerms::terms",
            Field::PanelTop => "PanelOptions::top",
            Field::OutlierThreshold => "Outliers::threshold",
        }
    }

    /// The key of the field in a plant TOML file, for the settle fields a file can set
    /// (`step_um`, `window_um`, `bias`, `bias_uncertainty`, `horizon`, `hold`); `None` for the
    /// others.
    pub const fn file_key(self) -> Option<&'static str> {
        match self {
            Field::StepUm => Some("step_um"),
            Field::WindowUm => Some("window_um"),
            Field::Bias => Some("bias"),
            Field::BiasUncertainty => Some("bias_uncertainty"),
            Field::Horizon => Some("horizon"),
            Field::Hold => Some("hold"),
            _ => None,
        }
    }
}

impl Field {
    /// Byte ranges of whole occurrences of this field's name in `text`: not preceded by a
    /// letter, digit, `_` or `:` and not followed by a letter, digit or `_`
    /// (`SettleSpec::bias` is not found in `SettleSpec::bias_uncertainty`).
    pub fn find_in(self, text: &str) -> Vec<std::ops::Range<usize>> {
        let word = |c: char| c.is_alphanumeric() || c == '_';
        let name = self.name();
        text.match_indices(name)
            .map(|(i, _)| i..i + name.len())
            .filter(|r| {
                let before = text[..r.start].chars().next_back();
                let after = text[r.end..].chars().next();
                !before.is_some_and(|c| word(c) || c == ':') && !after.is_some_and(word)
            })
            .collect()
    }

    /// `text` with every whole occurrence of a setting name ([`Field::find_in`]) replaced, in
    /// order: `rename(field, rest)` gets the field and the text after its name and gives the
    /// replacement and how many bytes of `rest` it takes in too (a value it rewrites with the
    /// name; 0 for none). The command line's messages name flags this way, the Python
    /// package's keywords.
    pub fn rename_in(text: &str, rename: impl Fn(Field, &str) -> (String, usize)) -> String {
        let mut found: Vec<(std::ops::Range<usize>, Field)> = Field::ALL
            .iter()
            .flat_map(|&f| f.find_in(text).into_iter().map(move |r| (r, f)))
            .collect();
        found.sort_by_key(|(r, _)| r.start);
        let mut out = String::with_capacity(text.len());
        let mut at = 0;
        for (r, f) in found {
            if r.start < at {
                continue;
            }
            out.push_str(&text[at..r.start]);
            let (name, taken) = rename(f, &text[r.end..]);
            out.push_str(&name);
            at = r.end + taken;
        }
        out.push_str(&text[at..]);
        out
    }
}

impl fmt::Display for Field {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::Field;

    /// Reference: the names themselves. Each name is found exactly once in a text made of all
    /// of them, so no whole name is taken for another (`SettleSpec::bias` is a prefix of
    /// `SettleSpec::bias_uncertainty`).
    #[test]
    fn every_name_is_found_only_as_itself() {
        let all: Vec<&str> = Field::ALL.iter().map(|f| f.name()).collect();
        let text = format!("{} (end)", all.join(", "));
        for f in Field::ALL {
            let found = f.find_in(&text);
            assert_eq!(found.len(), 1, "{f}: {found:?}");
            assert_eq!(&text[found[0].clone()], f.name());
        }
        assert!(
            Field::Bias
                .find_in("SettleSpec::bias_uncertainty")
                .is_empty()
        );
        assert!(Field::Bias.find_in("XSettleSpec::bias").is_empty());
        assert_eq!(Field::Bias.find_in("SettleSpec::bias: 3").len(), 1);
    }
}
