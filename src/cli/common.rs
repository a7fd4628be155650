//! Flags shared by several commands.

use crate::Field;
use crate::SettleSpec;
use crate::{
    ColumnMap, Log, Units, log::DEFAULT_BIAS_COL, log::DEFAULT_TIME_COL, log::DEFAULT_TRACK_COL,
    log::LogSchema, log::check_unit_label,
};
use anyhow::Context;
use clap::Args;
use std::path::{Path, PathBuf};

/// The one table library setting → command-line flag (as ripgrep's flags → `HiArgs`). The
/// library's errors name settings ([`Field`]); [`with_flags`] renders each as its flag in every
/// message the CLI prints. `None`: no command sets the field (a library-only setting such as
/// `FitOptions::grid`), so its name stays. Every [`Field`] is listed once (a test checks).
pub(crate) const FLAGS: [(Field, Option<&str>); 42] = [
    (Field::TimeColumn, Some("--time-col")),
    (Field::TrackColumn, Some("--track-col")),
    (Field::BiasColumn, Some("--bias-col")),
    (Field::BiasUnit, Some("--bias-unit")),
    (Field::PositionUnit, Some("--track-unit")),
    (Field::Sequence, Some("--sequence")),
    (Field::Disabled, Some("--disable")),
    (Field::SeekCount, Some("--n")),
    (Field::Span, Some("--span")),
    (Field::Center, Some("--center")),
    (Field::DwellMin, Some("--dwell-min")),
    (Field::DwellMax, Some("--dwell-max")),
    (Field::Script, Some("--script")),
    (Field::StepUm, Some("--step-um")),
    (Field::WindowUm, Some("--window-um")),
    (Field::Bias, Some("--bias")),
    (Field::BiasUncertainty, Some("--bias-uncertainty")),
    (Field::Horizon, Some("--horizon")),
    (Field::Hold, Some("--hold")),
    (Field::RankTolerance, None),
    (Field::Grid, None),
    (Field::Refine, None),
    (Field::Folds, Some("--folds")),
    (Field::BlockLen, None),
    (Field::Alpha, Some("--alpha")),
    (Field::Permutations, Some("--permutations")),
    (Field::MaxBins, None),
    (Field::MinBinRows, None),
    (Field::MaxDiscrete, None),
    (Field::LjungBoxLags, None),
    (Field::NullBlock, None),
    (Field::MinEffect, None),
    (Field::VerifyFolds, Some("--verify-folds")),
    (Field::VerifyCandidates, None),
    (Field::MinZ, None),
    (Field::MaxSteps, Some("--max-steps")),
    (Field::RandomSeeks, Some("--seeks")),
    (Field::StoryPermutations, None),
    (Field::SettlePreset, None),
    (Field::LadderTerms, Some("--terms")),
    (Field::PanelTop, Some("--top")),
    (Field::OutlierThreshold, Some("--threshold")),
];

/// The flag that sets `field`, from [`FLAGS`]; `None` for a library-only setting.
pub(crate) fn flag(field: Field) -> Option<&'static str> {
    FLAGS
        .iter()
        .find(|(f, _)| *f == field)
        .and_then(|(_, flag)| *flag)
}

/// How the CLI names `field` in a message: its flag (`--span`), or for a setting a plant file
/// can also set, its key and flag (`window_um (--window-um)`), since the value may come from
/// either; a library-only setting keeps its library name.
fn cli_name(field: Field) -> String {
    match (flag(field), field.file_key()) {
        (Some(flag), Some(key)) => format!("{key} ({flag})"),
        (Some(flag), None) => flag.to_string(),
        (None, _) => field.name().to_string(),
    }
}

/// `text` with every whole occurrence of a library setting name replaced by the CLI's name for
/// it ([`cli_name`], through [`Field::rename_in`]).
pub(crate) fn with_flags(text: &str) -> String {
    Field::rename_in(text, |f, _| (cli_name(f), 0))
}

/// Column-name and unit flags accepted by every command that reads a log.
#[derive(Debug, Clone, Args)]
pub(crate) struct ColumnArgs {
    /// Name of the time column (seconds).
    #[arg(long, default_value = DEFAULT_TIME_COL, value_name = "NAME")]
    pub time_col: String,
    /// Name of the position column (the seek target; tracks or any position unit).
    #[arg(long, default_value = DEFAULT_TRACK_COL, value_name = "NAME")]
    pub track_col: String,
    /// Name of the measured-bias column (counts or any force unit).
    #[arg(long, default_value = DEFAULT_BIAS_COL, value_name = "NAME")]
    pub bias_col: String,
    /// Unit label of the bias (e.g. N, mA); default: the log's `# bias_unit` metadata, else
    /// counts for the column `bias`, else the bias column's name.
    #[arg(long, value_name = "LABEL", value_parser = unit_label)]
    pub bias_unit: Option<String>,
    /// Unit label of the position (e.g. m, mm); default: the log's `# position_unit` metadata,
    /// else tracks for the column `track`, else the track column's name.
    #[arg(long, value_name = "LABEL", value_parser = unit_label)]
    pub track_unit: Option<String>,
    /// Field delimiter: `,` `;` or `tab` (also `comma`, `semicolon`, `\t`); default: sniffed
    /// from the header. With `;` or tab a number may use a decimal comma (`0,25`).
    #[arg(allow_negative_numbers = true, long, value_name = "CHAR", value_parser = delimiter)]
    pub delimiter: Option<u8>,
}

/// Parses `--delimiter` into its byte (clap names the flag in the error).
fn delimiter(text: &str) -> Result<u8, String> {
    match text {
        "," | "comma" => Ok(b','),
        ";" | "semicolon" => Ok(b';'),
        "tab" | "\\t" | "\t" => Ok(b'\t'),
        _ => Err(format!(
            "`{text}` is not a delimiter biasctl reads; use `,`, `;` or `tab`"
        )),
    }
}

/// Validates a `--bias-unit` / `--track-unit` label (clap names the flag in the error).
fn unit_label(label: &str) -> Result<String, String> {
    check_unit_label(label)
        .map(str::to_string)
        .map_err(str::to_string)
}

impl Default for ColumnArgs {
    /// The default column names, as when no flag is given.
    fn default() -> Self {
        let m = ColumnMap::default();
        Self {
            time_col: m.time,
            track_col: m.track,
            bias_col: m.bias,
            bias_unit: None,
            track_unit: None,
            delimiter: None,
        }
    }
}

impl ColumnArgs {
    /// The validated column map.
    pub(crate) fn map(&self) -> ColumnMap {
        ColumnMap {
            time: self.time_col.clone(),
            track: self.track_col.clone(),
            bias: self.bias_col.clone(),
            delimiter: self.delimiter,
        }
    }

    /// The units of a log read with these flags: the unit flags first, then the log's metadata,
    /// then the column defaults ([`Units::resolve`]).
    pub(crate) fn units(&self, schema: &LogSchema) -> anyhow::Result<Units> {
        Ok(Units::resolve(
            self.bias_unit.as_deref(),
            self.track_unit.as_deref(),
            schema,
        )?)
    }

    /// The units of a log read for `model`: a unit named by a flag or by the log's metadata
    /// must be the one the model was fitted in (else an error naming the flag); one the column
    /// name gave is the model's, so a model fitted with `--bias-unit N` prints N without the
    /// flag.
    pub(crate) fn units_for_model(
        &self,
        schema: &LogSchema,
        model: &crate::FittedModel,
    ) -> anyhow::Result<Units> {
        let mut units = self.units(schema)?;
        if let Some(fitted) = &model.columns.units {
            let (bias, track) = (self.bias_unit.is_some(), self.track_unit.is_some());
            units = units.for_model(fitted, bias, track, schema);
        }
        model.check_units(&units)?;
        Ok(units)
    }

    /// Reads the whole log at `path` for `model`: [`ColumnArgs::read_log`], in the units
    /// [`ColumnArgs::units_for_model`] gives.
    pub(crate) fn read_log_for(
        &self,
        path: &Path,
        model: &crate::FittedModel,
    ) -> anyhow::Result<Log> {
        let mut log = self.read_log(path)?;
        log.schema.units = self.units_for_model(&log.schema, model)?;
        Ok(log)
    }

    /// Reads the whole log at `path` with these column names and unit labels.
    pub(crate) fn read_log(&self, path: &Path) -> anyhow::Result<Log> {
        let mut log = Log::read(path, &self.map())?;
        for note in &log.schema.notes {
            eprintln!("note: {note}");
        }
        log.schema.units = self.units(&log.schema)?;
        Ok(log)
    }
}

/// A log to read (`--data`) and its column names.
#[derive(Debug, Clone, Args)]
pub(crate) struct LogArgs {
    /// The measurement log (CSV with `time_s`, `track`, `bias` and optional covariate columns).
    #[arg(long, value_name = "LOG.csv")]
    pub data: PathBuf,
    #[command(flatten)]
    pub columns: ColumnArgs,
}

/// How the direction of motion is read: `--deadband X` or `--velocity-col NAME`;
/// neither: a deadband estimated from the position noise on a dense time series, raw position
/// steps on a log of seeks.
#[derive(Debug, Clone, Default, Args)]
pub(crate) struct DirectionArgs {
    /// Direction reverses only once the position has come back more than X (the log's position
    /// unit, ≥ 0; 0: every step against the direction) from its furthest point. Default: the
    /// range the position noise spans over the log (2·√(2 ln n) × its std) on a densely sampled
    /// log, 0 on a log of seeks.
    #[arg(
        long,
        value_name = "X",
        conflicts_with = "velocity_col",
        allow_hyphen_values = true
    )]
    pub deadband: Option<f64>,
    /// Read the direction from the sign of this (velocity) column instead of position steps.
    #[arg(long, value_name = "NAME")]
    pub velocity_col: Option<String>,
}

impl DirectionArgs {
    /// The library setting these flags ask for (checked: a bad deadband names the flag).
    pub(crate) fn setting(&self) -> anyhow::Result<crate::history::DirectionSetting> {
        use crate::history::DirectionSetting;
        let s = match (&self.deadband, &self.velocity_col) {
            (Some(d), _) => DirectionSetting::Deadband(*d),
            (None, Some(c)) => DirectionSetting::Velocity(c.clone()),
            (None, None) => DirectionSetting::Auto,
        };
        s.validate()?;
        Ok(s)
    }

    /// The checked default fit settings with this direction setting.
    pub(crate) fn fit_options(&self) -> anyhow::Result<crate::CheckedFitOptions> {
        Ok(crate::FitOptions {
            direction: self.setting()?,
            ..crate::FitOptions::default()
        }
        .check()?)
    }
}

/// The plant and scenario flags of the settle analysis (`settle`, `plot bounds|responses`).
#[derive(Debug, Clone, Default, Args)]
pub(crate) struct SettleArgs {
    /// A built-in plant and scenario: paper1997 or modern (default paper1997).
    #[arg(long, value_name = "NAME", conflicts_with = "plant")]
    pub preset: Option<String>,
    /// A plant TOML file with every preset parameter (see data/plant_*.toml).
    #[arg(long, value_name = "FILE.toml")]
    pub plant: Option<PathBuf>,
    /// Step length in µm (handoff e0 = −step from rest).
    #[arg(long, value_name = "X", allow_hyphen_values = true)]
    pub step_um: Option<f64>,
    /// Half-width δ of the settle window in µm.
    #[arg(long, value_name = "D", allow_hyphen_values = true)]
    pub window_um: Option<f64>,
    /// Bias d in counts (sets the integrator's converged value).
    #[arg(long, value_name = "B", allow_hyphen_values = true)]
    pub bias: Option<f64>,
    /// Bias uncertainty Δb in counts for the robust choice.
    #[arg(long, value_name = "DB", allow_hyphen_values = true)]
    pub bias_uncertainty: Option<f64>,
    /// Horizon N in samples.
    #[arg(allow_negative_numbers = true, long, value_name = "N")]
    pub horizon: Option<usize>,
    /// Samples M that must lie in the window at the end of the horizon.
    #[arg(allow_negative_numbers = true, long, value_name = "M")]
    pub hold: Option<usize>,
}

impl SettleArgs {
    /// Whether any of these flags was given.
    pub(crate) fn any(&self) -> bool {
        self.preset.is_some()
            || self.plant.is_some()
            || self.step_um.is_some()
            || self.window_um.is_some()
            || self.bias.is_some()
            || self.bias_uncertainty.is_some()
            || self.horizon.is_some()
            || self.hold.is_some()
    }

    /// The preset or plant file with the flags' overrides applied (validated later by
    /// `SettleSpec::check`).
    pub(crate) fn spec(&self) -> anyhow::Result<SettleSpec> {
        let mut spec = match &self.plant {
            Some(path) => SettleSpec::from_toml_file(path)?,
            None => {
                let name = self.preset.as_deref().unwrap_or("paper1997");
                SettleSpec::preset(name)
                    .with_context(|| format!("--preset {}", crate::io::quote(name)))?
            }
        };
        let overrides = [
            (self.step_um, &mut spec.step_um),
            (self.window_um, &mut spec.window_um),
            (self.bias, &mut spec.bias),
            (self.bias_uncertainty, &mut spec.bias_uncertainty),
        ];
        for (flag, field) in overrides {
            if let Some(v) = flag {
                *field = v;
            }
        }
        if let Some(v) = self.horizon {
            spec.horizon = v;
        }
        if let Some(v) = self.hold {
            spec.hold = v;
        }
        Ok(spec)
    }
}

/// Refuses, before anything runs, an output flag naming the same file as an input flag or as
/// another output flag ([`crate::io::check_paths`]); each path comes with its flag.
pub(crate) fn refuse_clashes(
    inputs: &[(&str, Option<&Path>)],
    outputs: &[(&str, Option<&Path>)],
) -> anyhow::Result<()> {
    let ins: Vec<(&str, &Path)> = inputs
        .iter()
        .filter_map(|&(f, p)| p.map(|p| (f, p)))
        .collect();
    let outs: Vec<(&str, &Path)> = outputs
        .iter()
        .filter_map(|&(f, p)| p.map(|p| (f, p)))
        .collect();
    Ok(crate::io::check_paths(&ins, &outs)?)
}

/// Refuses, before anything runs, a file output (not `-`) that is an existing folder or whose
/// folder does not exist: the write at the end would fail after all the work (biasctl makes
/// the folders of a folder output, `--out DIR`, but not of a file).
pub(crate) fn refuse_missing_folders(outputs: &[(&str, Option<&Path>)]) -> anyhow::Result<()> {
    for &(flag, path) in outputs {
        let Some(path) = path.filter(|p| p.as_os_str() != crate::log::STDIN_PATH) else {
            continue;
        };
        let shown = crate::io::quote(&path.display().to_string());
        if path.is_dir() {
            anyhow::bail!("{flag} {shown} is a folder; give a file name");
        }
        let folder = path.parent().filter(|p| !p.as_os_str().is_empty());
        if let Some(folder) = folder
            && !folder.is_dir()
        {
            anyhow::bail!(
                "{flag} {shown}: the folder {} does not exist (or is not a folder); create it first",
                crate::io::quote(&folder.display().to_string())
            );
        }
    }
    Ok(())
}

/// The staging folder of a folder output `--out DIR` ([`crate::io::StagedDir`]), made before the
/// work so that a path that is a file or cannot be written fails at once, named as the flag.
pub(crate) fn stage_out(dir: &Path) -> anyhow::Result<crate::io::StagedDir> {
    let shown = crate::io::quote(&dir.display().to_string());
    if dir.exists() && !dir.is_dir() {
        anyhow::bail!("--out {shown}: is a file; --out takes a directory");
    }
    crate::io::StagedDir::create(dir).with_context(|| format!("--out {shown}"))
}

/// Prints a warning (stderr) when `positions` of `file` go beyond the position range `model` was
/// fitted on: its position terms are extrapolated there and nothing else would show it.
pub(crate) fn warn_outside_range(model: &crate::FittedModel, file: &str, positions: &[f64]) {
    if let Some(w) = model.outside_range(positions) {
        eprintln!("warning: {file}: {w}");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every library setting is in the table exactly once, and every flag there is a flag some
    /// command accepts (reference: clap's own command tree).
    #[test]
    fn every_field_has_one_row_and_every_flag_exists() {
        for f in Field::ALL {
            let rows = FLAGS.iter().filter(|(g, _)| *g == f).count();
            assert_eq!(rows, 1, "{f} has {rows} rows in FLAGS");
        }
        assert_eq!(FLAGS.len(), Field::ALL.len());
        let cmd = <super::super::Cli as clap::CommandFactory>::command();
        let mut known = std::collections::BTreeSet::new();
        // Every command's flags, nested ones (`fleet outliers`) included.
        let mut todo: Vec<&clap::Command> = cmd.get_subcommands().collect();
        while let Some(sub) = todo.pop() {
            for a in sub.get_arguments() {
                if let Some(l) = a.get_long() {
                    known.insert(format!("--{l}"));
                }
            }
            todo.extend(sub.get_subcommands());
        }
        for (f, flag) in FLAGS {
            if let Some(flag) = flag {
                assert!(
                    known.contains(flag),
                    "{f}: {flag} is no flag of any command"
                );
            }
        }
    }

    /// Every library error that names a flagged setting is printed with the flag and without
    /// the library name (reference: the table row itself), through the same path `main` uses.
    #[test]
    fn every_message_names_the_flag_not_the_field() {
        for (f, flag) in FLAGS {
            let Some(flag) = flag else { continue };
            let err = std::io::Error::other(format!("{f} 0: must be > 0; see {f}"));
            let text = super::super::message(&err);
            assert_eq!(text.matches(flag).count(), 2, "{text}");
            assert!(!text.contains(f.name()), "{text}");
        }
        // A prefix of a longer name is not taken for it; the file key stays for settle fields.
        assert_eq!(
            with_flags("SettleSpec::bias_uncertainty must be ≥ 0, SettleSpec::bias 3"),
            "bias_uncertainty (--bias-uncertainty) must be ≥ 0, bias (--bias) 3"
        );
        assert_eq!(
            with_flags("name it with ColumnMap::track."),
            "name it with --track-col."
        );
    }

    /// No library source outside its tests names a flag of the table: the library names
    /// settings, the CLI alone maps them to flags (reference: the source text itself).
    #[test]
    fn the_library_names_no_flag_of_the_table() {
        let flags: Vec<&str> = FLAGS.iter().filter_map(|(_, f)| *f).collect();
        let mut stack = vec![std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("src")];
        let mut offenders = Vec::new();
        while let Some(dir) = stack.pop() {
            for entry in std::fs::read_dir(&dir).unwrap() {
                let path = entry.unwrap().path();
                if path.ends_with("cli") || path.ends_with("main.rs") {
                    continue;
                }
                if path.is_dir() {
                    stack.push(path);
                    continue;
                }
                let text = std::fs::read_to_string(&path).unwrap();
                let code = text.split("#[cfg(test)]").next().unwrap_or_default();
                for (i, line) in code.lines().enumerate() {
                    let line = line.trim_start();
                    if line.starts_with("//") {
                        continue;
                    }
                    for flag in &flags {
                        let quoted = |c: char| line.contains(&format!("{flag}{c}"));
                        if quoted('"') || quoted(' ') || quoted(')') || quoted(',') {
                            offenders.push(format!("{}:{}: {flag}", path.display(), i + 1));
                        }
                    }
                }
            }
        }
        assert!(offenders.is_empty(), "{offenders:#?}");
    }
}
