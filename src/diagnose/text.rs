//! The diagnosis in words: the summary, the text report, the JSON and the per-feature CSVs.

use std::path::{Path, PathBuf};

use crate::io::write_atomic;
use crate::log::fmt_float;
use crate::numeric::stats;

use super::advice;
use super::report::{is_pair_only, is_skipped};
use super::values::short;
use super::{DiagnoseError, Diagnosis, FeatureReport};

pub(super) fn percent(x: f64) -> String {
    format!("{:.1} %", 100.0 * x)
}

/// A p-value for a table cell: `< 0.0001` below 1e-4 (the permutation and dip tests resolve
/// nothing finer), else four significant decimals.
/// "`drift` is following `temp_c`: {lead}50 %{mid}drift{tail}10 % of the residual alone: add
/// `col:temp_c`" — one absorption in words (the summary's sentence and the text's line differ
/// only in the joining words).
pub(super) fn absorbed_text(a: &super::Absorption, lead: &str, mid: &str, tail: &str) -> String {
    format!(
        "`{}` is following `{}`: {lead}{}{mid}{}{tail}{} of the residual alone{}",
        a.term,
        a.feature,
        percent(a.explained_with_term),
        a.term,
        percent(a.explained_residual),
        a.suggested_term
            .as_deref()
            .map(|t| format!(": add `{t}`"))
            .unwrap_or_default()
    )
}

pub(super) fn p_text(p: f64) -> String {
    if p < 1e-4 {
        "< 0.0001".to_string()
    } else if p < 1e-3 {
        format!("{p:.4}")
    } else {
        format!("{p:.3}")
    }
}

/// A p-value in a sentence: `p < 0.0001` or `p = 0.012`.
pub(super) fn p_sentence(p: f64) -> String {
    let t = p_text(p);
    if t.starts_with('<') {
        format!("p {t}")
    } else {
        format!("p = {t}")
    }
}

/// The advice sentence for one flagged feature (`unit`: the residual's).
pub(super) fn advice_line(f: &FeatureReport, residual_std: f64, unit: &str) -> String {
    let mut s = format!(
        "The residual{} follows `{}`: it {}; `{}` explains {} of the residual variance out of \
         sample ({}, family-wise).",
        if f.by_direction {
            " times the direction of the last move"
        } else {
            ""
        },
        f.name,
        f.shape.describe(&f.name, f.shape_at),
        f.name,
        percent(f.explained),
        p_sentence(f.p_value)
    );
    match &f.suggested_term {
        Some(t) => {
            s.push_str(&format!(
                " Add `{t}`: expected error std ≈ {} {unit} (from {}).",
                short(f.expected_std),
                short(residual_std)
            ));
            if t == crate::model::terms::seek::HEAD && !f.by_direction {
                s.push_str(&format!(
                    " In a state-space model use `{}` instead.",
                    advice::DAHL_TERM
                ));
            }
        }
        None => s.push_str(" No further term addresses it."),
    }
    if let Some(note) = &f.note {
        s.push_str(&format!(" Note: {note}."));
    }
    s
}

/// The summary of `d` again, after absorption, warnings or verification were added.
pub(crate) fn extend_summary(d: &Diagnosis) -> String {
    summary(d, d.rows, d.alpha)
}

/// Sentences on the verified edits, absorbed effects and warnings, in that order.
pub(super) fn model_sentences(d: &Diagnosis) -> Vec<String> {
    let mut parts = Vec::new();
    let unit = &d.units.bias;
    if let Some(v) = &d.verification {
        if let Some(why) = &v.not_run {
            parts.push(format!("Not verified: {why}."));
        }
        match v.best() {
            Some(e) => parts.push(format!(
                "Verified by refitting ({} folds of consecutive seeks, out of sample): `{}` \
                 ({}) takes the error std from {} to {} {unit} ({} of the error variance, \
                 z = {:.1}).",
                v.folds,
                e.edit,
                e.feature,
                short(e.std_before),
                short(e.std_after),
                percent(e.gain),
                e.z
            )),
            None if !v.edits.is_empty() => parts.push(format!(
                "No suggested edit is verified by refitting: the best, `{}`, changes the \
                 out-of-sample error std from {} to {} {unit} ({} of the variance, z = {:.1}): \
                 {}.",
                v.edits[0].edit,
                short(v.edits[0].std_before),
                short(v.edits[0].std_after),
                percent(v.edits[0].gain),
                v.edits[0].z,
                v.why_not_verified(&v.edits[0])
            )),
            None => {}
        }
        if let Some(r) = &v.second_round {
            parts.extend(second_round_sentence(v, r, unit));
        }
    }
    for a in &d.absorbed {
        parts.push(format!(
            "{}.",
            absorbed_text(
                a,
                "it explains ",
                " of the residual plus ",
                "'s contribution but "
            )
        ));
    }
    for w in &d.warnings {
        parts.push(format!("Warning: {w}."));
    }
    for i in &d.interactions {
        parts.push(format!(
            "`{}` × `{}` together explain {} of what the single features left, against {} for \
             the better alone: an interaction no single feature shows; try `{}`.",
            i.a,
            i.b,
            percent(i.explained_pair),
            percent(i.best_single),
            i.suggested_term
        ));
    }
    if let Some(g) = d.global.as_ref().filter(|g| g.remains) {
        parts.push(format!(
            "Global check: the joint cells of {} explain {} of what the single features left, \
             against {} for the best single one: something remains that no single feature \
             explains.",
            g.features
                .iter()
                .map(|f| format!("`{f}`"))
                .collect::<Vec<_>>()
                .join(", "),
            percent(g.explained_joint),
            percent(g.best_single)
        ));
    }
    parts
}

/// The summary's sentence on the second verification round: what holds on top of the best
/// edit and the two together as the model to fit, or that nothing does.
pub(super) fn second_round_sentence(
    v: &super::Verification,
    r: &super::SecondRound,
    unit: &str,
) -> Option<String> {
    let e = r.edits.first()?;
    Some(match &r.combined {
        Some(c) => format!(
            "On top of `{}`, `{}` ({}) holds too: refitted with both, the out-of-sample error \
             std goes from {} to {} {unit} ({} of the variance left, z = {:.1}); together they \
             take it from {} to {} {unit} ({} of the error variance): fit `{}`.",
            r.on_top_of,
            e.edit,
            e.feature,
            short(e.std_before),
            short(e.std_after),
            percent(e.gain),
            e.z,
            short(c.std_before),
            short(c.std_after),
            percent(c.gain),
            c.terms
        ),
        None => format!(
            "On top of `{}`, nothing else holds: the best, `{}` ({}), gains {} of the variance \
             left (z = {:.1}): {}.",
            r.on_top_of,
            e.edit,
            e.feature,
            percent(e.gain),
            e.z,
            v.why_not_verified(e)
        ),
    })
}

/// Why no feature is flagged, naming the rule that decided it: the strongest feature that is
/// significant but below the practical minimum (with its own note's figures) and any others,
/// or that none is significant at `alpha`.
fn nothing_flagged(d: &Diagnosis, n: usize, alpha: f64) -> String {
    let residual = format!(
        "the residual (std {} {}, {n} rows)",
        short(d.residual_std),
        d.units.bias
    );
    let below: Vec<&FeatureReport> = d
        .features
        .iter()
        .filter(|f| f.reason == super::Reason::BelowPracticalMinimum)
        .collect();
    let Some(first) = below.first() else {
        return format!(
            "No candidate feature is flagged: {}: none explains {residual} beyond noise at the \
             {} level (family-wise).",
            super::Reason::NotSignificant,
            percent(alpha)
        );
    };
    // The feature's note begins with its rule and the figures that decided it.
    let why = first
        .note
        .as_deref()
        .and_then(|n| n.split("; ").next())
        .map(str::to_string)
        .unwrap_or_else(|| super::Reason::BelowPracticalMinimum.to_string());
    let mut s = format!(
        "No candidate feature is flagged in {residual}: the strongest significant one, `{}`, is \
         {why}.",
        first.name
    );
    if below.len() > 1 {
        let others: Vec<String> = below[1..].iter().map(|f| format!("`{}`", f.name)).collect();
        s.push_str(&format!(
            " Also significant but {}: {}.",
            super::Reason::BelowPracticalMinimum,
            others.join(", ")
        ));
    }
    s.push_str(&format!(
        " The others are {} at the {} level.",
        super::Reason::NotSignificant,
        percent(alpha)
    ));
    s
}

/// The plain-words summary of a diagnosis.
pub(crate) fn summary(d: &Diagnosis, n: usize, alpha: f64) -> String {
    let mut parts = model_sentences(d);
    let flagged: Vec<&FeatureReport> = d.features.iter().filter(|f| f.flagged).collect();
    match flagged.first() {
        Some(f) => {
            parts.push(advice_line(f, d.residual_std, &d.units.bias));
            if flagged.len() > 1 {
                let others: Vec<String> = flagged[1..]
                    .iter()
                    .map(|f| {
                        let term = f
                            .suggested_term
                            .as_deref()
                            .map(|t| format!(", add `{t}`"))
                            .unwrap_or_default();
                        match f.explained_beyond_previous {
                            Some(b) => format!(
                                "`{}` ({} alone, {} beyond the ones before{term})",
                                f.name,
                                percent(f.explained),
                                percent(b)
                            ),
                            None => format!("`{}` ({}{term})", f.name, percent(f.explained)),
                        }
                    })
                    .collect();
                parts.push(format!(
                    "Also flagged, in order of what each adds beyond the ones before: {}.",
                    others.join(", ")
                ));
            }
        }
        None => parts.push(nothing_flagged(d, n, alpha)),
    }
    let w = &d.whiteness;
    match (w.white, w.ljung_box_p) {
        (false, Some(p)) => parts.push(format!(
            "The residuals are not white in seek order (lag-1 autocorrelation {:.2}, Ljung–Box \
             {}): something slow is left.",
            w.lag1,
            p_sentence(p)
        )),
        _ => parts.push(format!(
            "The residuals look white in seek order (lag-1 autocorrelation {:.2}).",
            w.lag1
        )),
    }
    if let Some(t) = d.dip.as_ref().filter(|t| t.rejects_unimodality(0.05)) {
        parts.push(format!(
            "Their histogram has more than one hump (Hartigans' dip test {}): separate \
             populations, as from a missing direction or hysteresis term.",
            p_sentence(t.p_value)
        ));
    }
    if let Some(pos) = d.features.iter().find(|f| f.name == "position")
        && let (Some(slope), Some(p)) = (pos.slope, pos.slope_p)
        && p <= alpha
    {
        parts.push(format!(
            "A linear trend against position remains ({} {}, {}).",
            short(slope),
            d.units.per_position(),
            p_sentence(p)
        ));
    }
    let skipped: Vec<String> = d
        .features
        .iter()
        .filter(|f| is_skipped(f) && !is_pair_only(f))
        .map(|f| format!("`{}`", f.name))
        .collect();
    if !skipped.is_empty() {
        parts.push(format!(
            "Skipped (constant or undefined): {}.",
            skipped.join(", ")
        ));
    }
    parts.join(" ")
}

impl Diagnosis {
    /// The JSON of the contract (pretty-printed).
    /// Through the one JSON writer: a non-finite number is refused naming its key path.
    pub fn to_json(&self) -> Result<String, crate::io::OutputError> {
        crate::io::json::to_string_pretty(self)
    }

    /// The report of feature `name`, if present.
    pub fn feature(&self, name: &str) -> Option<&FeatureReport> {
        self.features.iter().find(|f| f.name == name)
    }

    /// The text block of the second verification round: each edit scored on top of the best
    /// one, what could not be applied, and the combined advice.
    /// One verified (or refused) edit as a line of the text output: the edit, its feature, the
    /// error std before → after, the gain and z, and why it is not verified when it is not.
    fn edit_line(&self, v: &super::Verification, e: &super::VerifiedEdit) -> String {
        format!(
            "  {:<32} {:<24} std {} → {} {}, gain {}, z {:.1}{}\n",
            e.edit,
            format!("({})", e.feature),
            short(e.std_before),
            short(e.std_after),
            self.units.bias,
            percent(e.gain),
            e.z,
            if e.verified {
                String::new()
            } else {
                format!("  (not verified: {})", v.why_not_verified(e))
            }
        )
    }

    fn second_round_text(&self, v: &super::Verification, r: &super::SecondRound) -> String {
        let unit = &self.units.bias;
        let mut out = format!(
            "\nSecond round, on top of `{}` (error std out of sample {}; stricter bar):\n",
            r.on_top_of,
            short(r.std_before)
        );
        for e in &r.edits {
            out.push_str(&self.edit_line(v, e));
        }
        for x in &r.rejected {
            out.push_str(&format!(
                "  `{}` for `{}` on top: {}: {}\n",
                x.term, x.feature, x.reason, x.why
            ));
        }
        if let Some(c) = &r.combined {
            out.push_str(&format!(
                "  both hold: {} → std {} → {} {unit} ({} of the error variance); fit `{}`\n",
                c.edits.join(" + "),
                short(c.std_before),
                short(c.std_after),
                percent(c.gain),
                c.terms
            ));
        }
        out
    }

    /// A human-readable rendering: the ranking table, advice for every flagged feature, the
    /// residual checks and the summary.
    pub fn to_text(&self) -> String {
        let mut out = String::new();
        out.push_str(&format!(
            "Residual std: {} {}\n\n",
            short(self.residual_std),
            self.units.bias
        ));
        out.push_str(&format!(
            "{:<20} {:>9} {:>9} {:>9} {:>5}  {:<16} {:<22} {:>12}\n",
            "feature",
            "explained",
            "beyond",
            "p (fw)",
            "flag",
            "shape",
            "suggested term",
            "expected std"
        ));
        for f in &self.features {
            out.push_str(&format!(
                "{:<20} {:>9} {:>9} {:>9} {:>5}  {:<16} {:<22} {:>12}\n",
                if f.by_direction {
                    format!("{} ×dir", f.name)
                } else {
                    f.name.clone()
                },
                percent(f.explained),
                f.explained_beyond_previous
                    .map(percent)
                    .unwrap_or_else(|| "-".into()),
                p_text(f.p_value),
                if f.flagged { "*" } else { "" },
                serde_json::to_value(f.shape)
                    .ok()
                    .and_then(|v| v.as_str().map(str::to_string))
                    .unwrap_or_default(),
                f.suggested_term.as_deref().unwrap_or("-"),
                short(f.expected_std)
            ));
        }
        let flagged: Vec<&FeatureReport> = self.features.iter().filter(|f| f.flagged).collect();
        out.push_str("\nAdvice:\n");
        if flagged.is_empty() {
            out.push_str("  No feature is flagged: nothing to add.\n");
        }
        for (i, f) in flagged.iter().enumerate() {
            out.push_str(&format!(
                "  {}. {}\n",
                i + 1,
                advice_line(f, self.residual_std, &self.units.bias)
            ));
        }
        for f in self.features.iter().filter(|f| f.significant && !f.flagged) {
            if let Some(note) = &f.note {
                out.push_str(&format!("  `{}`: {note}.\n", f.name));
            }
        }
        for f in self.features.iter().filter(|f| is_skipped(f)) {
            if let Some(note) = &f.note {
                out.push_str(&format!("  `{}` {note}\n", f.name));
            }
        }
        out.push_str(&format!(
            "  (p: family-wise over all features, against a null that permutes blocks of {} \
             consecutive residuals, so serial correlation that short is not taken for an \
             effect; flagged: significant and adds at least the practical minimum beyond the \
             features ranked before it.)\n",
            self.null_block_len
        ));
        if let Some(v) = &self.verification {
            out.push_str(&format!(
                "\nVerified by refitting ({} folds of consecutive seeks; error std out of \
                 sample, {} before any edit):\n",
                v.folds,
                short(v.std_before)
            ));
            for e in &v.edits {
                out.push_str(&self.edit_line(v, e));
            }
            if let Some(why) = &v.not_run {
                out.push_str(&format!("  {why}\n"));
            }
            for r in &v.rejected {
                out.push_str(&format!(
                    "  `{}` for `{}`: {}: {}\n",
                    r.term, r.feature, r.reason, r.why
                ));
            }
            if let Some(r) = &v.second_round {
                out.push_str(&self.second_round_text(v, r));
            }
        }
        if !self.absorbed.is_empty() || !self.warnings.is_empty() {
            out.push_str("\nWhat adaptive terms absorbed:\n");
            for a in &self.absorbed {
                out.push_str(&format!(
                    "  {}\n",
                    absorbed_text(a, "", " of residual + ", " explained, ")
                ));
            }
            for w in &self.warnings {
                out.push_str(&format!("  warning: {w}\n"));
            }
        }
        let w = &self.whiteness;
        out.push_str("\nResidual checks:\n");
        out.push_str(&format!(
            "  whiteness: lag-1 autocorrelation {:.3}; Ljung–Box Q = {} over {} lags, {} → {}\n",
            w.lag1,
            w.ljung_box_q.map(short).unwrap_or_else(|| "-".into()),
            w.lags,
            w.ljung_box_p
                .map(p_sentence)
                .unwrap_or_else(|| "p -".into()),
            if w.white { "white" } else { "NOT white" }
        ));
        out.push_str(&format!(
            "  bimodality coefficient: {} (bimodal above {:.3})\n",
            self.bimodality
                .map(|b| format!("{b:.3}"))
                .unwrap_or_else(|| "-".into()),
            stats::BIMODALITY_THRESHOLD
        ));
        if let Some(t) = &self.dip {
            out.push_str(&format!(
                "  dip test of unimodality: D {:.4}, {} ({})\n",
                t.statistic,
                p_sentence(t.p_value),
                if t.rejects_unimodality(0.05) {
                    "more than one hump"
                } else {
                    "one hump"
                }
            ));
        }
        if let Some(pos) = self.feature("position")
            && let (Some(s), Some(p)) = (pos.slope, pos.slope_p)
        {
            out.push_str(&format!(
                "  trend against position: {} {}, {}\n",
                short(s),
                self.units.per_position(),
                p_sentence(p)
            ));
        }
        out.push_str(&format!("\nSummary: {}\n", self.summary));
        out
    }

    /// Writes, for every flagged feature and at least the three strongest usable ones, a CSV
    /// `residual_vs_<feature>.csv` in `dir` with columns
    /// `bin,lower,upper,centre,mean,std,count` (the bin of undefined values is labelled
    /// `missing` with empty lower/upper/centre). Returns the paths written.
    pub fn write_feature_csvs(&self, dir: &Path) -> Result<Vec<PathBuf>, DiagnoseError> {
        let mut written = Vec::new();
        let usable = self.features.iter().filter(|f| !is_skipped(f));
        for (rank, f) in usable.enumerate() {
            if rank >= 3 && !f.flagged {
                continue;
            }
            let path = dir.join(format!("residual_vs_{}.csv", file_safe(&f.name)));
            write_atomic(&path, |w| -> std::io::Result<()> {
                let mut w = crate::log::csv_writer(w);
                w.write_record(["bin", "lower", "upper", "centre", "mean", "std", "count"])?;
                for (i, c) in f.curve.iter().enumerate() {
                    let num = |x: Option<f64>| x.map(|v| fmt_float(v, 6)).unwrap_or_default();
                    let label = if c.centre.is_some() {
                        i.to_string()
                    } else {
                        "missing".to_string()
                    };
                    w.write_record([
                        label,
                        num(c.lower),
                        num(c.upper),
                        num(c.centre),
                        fmt_float(c.mean, 6),
                        fmt_float(c.std, 6),
                        c.count.to_string(),
                    ])?;
                }
                w.flush()
            })?;
            written.push(path);
        }
        Ok(written)
    }
}

/// `name` with every character outside `[A-Za-z0-9_-]` replaced by `_`.
pub(super) fn file_safe(name: &str) -> String {
    name.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '_' || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect()
}
