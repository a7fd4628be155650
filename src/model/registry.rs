//! The one table of built-in terms ([`BUILTINS`]): each entry gives the term's head (the spec
//! text before the first `:`), its syntax for help and error text, its parser and the function
//! that rebuilds its fitted form from a model file. [`parse_term`](super::terms::parse_term),
//! [`restore_term`](super::terms::restore_term) and [`builtin_names`] are derived from it.
//!
//! **Adding a built-in term** is one file and one line: write `src/model/terms/NAME.rs` with
//! the [`TermSpec`] (unfitted) and [`Term`] (fitted) types, a `parse` function
//! (`fn(&TermText) -> Result<Arc<dyn TermSpec>, SpecError>`) and, if its fitted form has saved
//! settings, `#[derive(Serialize, Deserialize)]` on the fitted type; declare the module in
//! `terms/mod.rs` (`pub mod NAME;`) and add its row to [`BUILTINS`]. Nothing in the solver
//! ([`crate::fit`](mod@crate::fit)) knows term names: a term reports its parameter count, whether it may drop
//! undetermined columns ([`TermCaps::droppable`](crate::model::TermCaps::droppable)) and its own fit warnings ([`Term::fit_warnings`]).
//!
//! ```
//! use biasctl::model::builtin_names;
//! assert!(builtin_names().starts_with("poly2, table[:SPACING], direction"));
//! ```

pub(crate) use super::cue::{Answer, AnswersFn, Cover, Cue, Law};
use super::term::{Term, TermSpec};
pub(crate) use super::term_text::TermText;
use super::terms::{
    bins, bump, by, covariate, dahl, direction, drift, intercept, lag, memory, memsum, play, poly,
    preisach, scale, seek, step, stribeck, table, viscous,
};
use super::{ModelError, SpecError};

use std::sync::Arc;

/// Parses the argument of a term (`None` for a bare head).
pub(crate) type ParseFn = fn(&TermText<'_>) -> Result<Arc<dyn TermSpec>, SpecError>;
/// Rebuilds a fitted term from its name and saved settings ([`Term::settings`]).
pub(crate) type RestoreBuiltinFn =
    fn(&str, &serde_json::Value) -> Result<Arc<dyn Term>, ModelError>;

/// One built-in term of the registry.
#[derive(Debug, Clone, Copy)]
pub(crate) struct BuiltinTerm {
    /// The head of its spec text (`poly2`, `dbins`, …).
    pub head: &'static str,
    /// Its syntax for messages (`table[:SPACING]`); `None` hides it from the list (`intercept`,
    /// which the fit adds by itself).
    pub syntax: Option<&'static str>,
    /// The parser of its spec text.
    pub parse: ParseFn,
    /// The restorer of its fitted form.
    pub restore: RestoreBuiltinFn,
    /// The spec text the diagnosis suggests for a pattern the term answers without naming a
    /// column (its head, or a richer default such as `dahl:4`).
    pub suggest: &'static str,
    /// The residual patterns the term answers ([`Cue`]), declared in the term's file.
    pub answers: AnswersFn,
    /// Heads of the terms of another model family it is not suggested beside (either way).
    pub conflicts: &'static [&'static str],
    /// When a model's term covers a suggestion of this term ([`Cover`]).
    pub cover: Cover,
    /// Whether it is a direction-signed state term whose force a covariate may scale
    /// (`scale:COL:TERM`).
    pub signed_state: bool,
    /// Whether its fitted form writes itself as C ([`Term::export_c`]); the export refuses the
    /// others by name. Held to it by this module's test.
    #[cfg_attr(not(test), allow(dead_code))]
    pub exports_c: bool,
}

/// A term that answers no pattern.
fn answers_none(_: Cue) -> Option<Answer> {
    None
}

/// Every built-in term, in the order [`builtin_names`] lists them.
pub(crate) static BUILTINS: &[BuiltinTerm] = &[
    row(
        poly::HEAD,
        Some("poly2"),
        poly::parse,
        restore_as::<poly::Poly2Term>,
    )
    .exports_c(),
    row(
        table::HEAD,
        Some("table[:SPACING]"),
        table::parse,
        restore_as::<table::TableTerm>,
    )
    .answering(table::answers)
    .exports_c(),
    row(
        direction::HEAD,
        Some("direction"),
        direction::parse,
        direction::restore,
    )
    .answering(direction::answers)
    .signed_state()
    .exports_c(),
    row(
        seek::HEAD,
        Some("seek[:KNOTS]"),
        seek::parse,
        restore_as::<seek::SeekTerm>,
    )
    .answering(seek::answers)
    .conflicting(&["dahl"])
    .exports_c(),
    row(
        memory::HEAD,
        Some("memory[:KNOTS]"),
        memory::parse,
        restore_as::<memory::MemoryTerm>,
    )
    .answering(memory::answers)
    .exports_c(),
    row(
        drift::HEAD,
        Some("drift[:ALPHA]"),
        drift::parse,
        restore_as::<drift::DriftTerm>,
    )
    .answering(drift::answers)
    .exports_c(),
    row(
        dahl::HEAD,
        Some("dahl, dahl:N"),
        dahl::parse,
        restore_as::<dahl::DahlTerm>,
    )
    .answering(dahl::answers)
    .suggesting(dahl::SUGGESTED)
    .conflicting(&["seek"])
    .covered(Cover::Count)
    .signed_state()
    .exports_c(),
    row(
        play::HEAD,
        Some("play[:N]"),
        play::parse,
        restore_as::<play::PlayTerm>,
    )
    .answering(play::answers)
    .covered(Cover::Family)
    .signed_state(),
    row(
        preisach::HEAD,
        Some("preisach[:N]"),
        preisach::parse,
        restore_as::<preisach::PreisachTerm>,
    )
    .covered(Cover::Count)
    .exports_c(),
    row(
        covariate::HEAD,
        Some("col:NAME"),
        covariate::parse,
        restore_as::<covariate::ColTerm>,
    )
    .answering(covariate::answers)
    .exports_c(),
    row(lag::HEAD, Some("lag:NAME"), lag::parse, lag::restore).answering(lag::answers),
    row(
        memsum::HEAD,
        Some("memsum"),
        memsum::parse,
        restore_as::<memsum::MemsumTerm>,
    )
    .answering(memsum::answers),
    row(
        viscous::HEAD,
        Some("viscous[:COL]"),
        viscous::parse,
        restore_as::<viscous::ViscousTerm>,
    )
    .answering(viscous::answers)
    .exports_c(),
    row(
        stribeck::HEAD,
        Some("stribeck[:COL][:DELTA]"),
        stribeck::parse,
        stribeck::restore,
    )
    .answering(stribeck::answers)
    .exports_c(),
    row(
        bins::HEAD,
        Some("bins:FEATURE[:KNOTS]"),
        bins::parse,
        bins::restore,
    )
    .answering(bins::answers)
    .exports_c(),
    row(
        bins::DBINS_HEAD,
        Some("dbins:FEATURE[:KNOTS]"),
        bins::parse,
        bins::restore,
    )
    .answering(bins::answers_by_direction)
    .exports_c(),
    row(
        bump::HEAD,
        Some("bump[:CENTRE:WIDTH]"),
        bump::parse,
        restore_as::<bump::BumpTerm>,
    )
    .exports_c(),
    row(
        step::HEAD,
        Some("step:COL[:T]"),
        step::parse,
        restore_as::<step::StepTerm>,
    )
    .exports_c(),
    row(
        by::HEAD,
        Some("by:A:B"),
        by::parse,
        restore_as::<by::ByTerm>,
    ),
    row(
        scale::HEAD,
        Some("scale:COL:TERM"),
        scale::parse,
        scale::restore,
    ),
    row(intercept::HEAD, None, intercept::parse, intercept::restore).exports_c(),
];

const fn row(
    head: &'static str,
    syntax: Option<&'static str>,
    parse: ParseFn,
    restore: RestoreBuiltinFn,
) -> BuiltinTerm {
    BuiltinTerm {
        head,
        syntax,
        parse,
        restore,
        suggest: head,
        answers: answers_none,
        conflicts: &[],
        cover: Cover::Exact,
        signed_state: false,
        exports_c: false,
    }
}

impl BuiltinTerm {
    /// The row answering the patterns of `answers`.
    const fn answering(self, answers: AnswersFn) -> Self {
        Self { answers, ..self }
    }
    /// The row suggested as `text` where it names no column.
    const fn suggesting(self, suggest: &'static str) -> Self {
        Self { suggest, ..self }
    }
    /// The row not suggested beside the heads `conflicts`.
    const fn conflicting(self, conflicts: &'static [&'static str]) -> Self {
        Self { conflicts, ..self }
    }
    /// The row covered as `cover` says.
    const fn covered(self, cover: Cover) -> Self {
        Self { cover, ..self }
    }
    /// The row of a direction-signed state term.
    const fn signed_state(self) -> Self {
        Self {
            signed_state: true,
            ..self
        }
    }
    /// The row of a term that writes itself as C.
    const fn exports_c(self) -> Self {
        Self {
            exports_c: true,
            ..self
        }
    }

    /// How many elements spec text `t` of this head asks for ([`Cover::Count`]).
    fn count(t: &str) -> Option<usize> {
        match t.split_once(':') {
            None => Some(1),
            Some((_, n)) => n.parse().ok(),
        }
    }
}

/// The terms that answer `cue`, best first, as spec text (`HEAD:name` where the term names
/// the feature or column `name`).
pub(crate) fn candidates(cue: Cue, name: &str) -> Vec<String> {
    let mut hits: Vec<(u8, String)> = BUILTINS
        .iter()
        .filter_map(|b| {
            let a = (b.answers)(cue)?;
            let text = if a.named {
                format!("{}:{name}", b.head)
            } else {
                b.suggest.to_string()
            };
            if a.parsed && super::terms::parse_term(&text).is_err() {
                return None;
            }
            Some((a.rank, text))
        })
        .collect();
    hits.sort_by_key(|h| h.0);
    hits.into_iter().map(|h| h.1).collect()
}

/// The head of spec text `t` (before the first `:`).
pub(crate) fn head(t: &str) -> &str {
    t.split(':').next().unwrap_or("")
}

/// Whether the model's term `have` covers the suggested term `want` (the same text, or the
/// same head as its row's [`Cover`] allows).
pub(crate) fn covers(have: &str, want: &str) -> bool {
    if have == want {
        return true;
    }
    match lookup(want) {
        Some(b) if head(have) == b.head && head(want) == b.head => match b.cover {
            Cover::Exact => false,
            Cover::Family => true,
            Cover::Count => matches!(
                (BuiltinTerm::count(want), BuiltinTerm::count(have)),
                (Some(w), Some(h)) if h >= w
            ),
        },
        _ => false,
    }
}

/// Whether `term` belongs to another model family than the model's term `have`
/// ([`BuiltinTerm::conflicts`]).
pub(crate) fn conflicts(have: &str, term: &str) -> bool {
    lookup(term).is_some_and(|b| head(term) == b.head && b.conflicts.contains(&head(have)))
}

/// Whether the model's term `t` is a direction-signed state term
/// ([`BuiltinTerm::signed_state`]).
pub(crate) fn is_signed_state(t: &str) -> bool {
    lookup(t).is_some_and(|b| b.signed_state)
}

/// The built-in term of spec text or model-file name `text` (looked up by its head).
pub(crate) fn lookup(text: &str) -> Option<&'static BuiltinTerm> {
    let head = text.split(':').next().unwrap_or("");
    BUILTINS.iter().find(|b| b.head == head)
}

/// The syntax of every listed built-in term, comma-separated, for messages.
pub fn builtin_names() -> String {
    BUILTINS
        .iter()
        .filter_map(|b| b.syntax)
        .collect::<Vec<_>>()
        .join(", ")
}

/// The head of every listed built-in term (`poly2`, `table`, …), once each, in registry order:
/// a list short enough for one line of a message.
pub(crate) fn builtin_heads() -> Vec<&'static str> {
    BUILTINS
        .iter()
        .filter(|b| b.syntax.is_some())
        .map(|b| b.head)
        .collect()
}

/// `; did you mean `x`?` for an unknown term's spec text: the closest built-in head to its
/// head, with the arguments as written (`dahll:4` → `dahl:4`), or nothing.
pub(crate) fn did_you_mean_term(text: &str) -> String {
    let (head, args) = text
        .split_once(':')
        .map_or((text, None), |(h, a)| (h, Some(a)));
    crate::io::words::closest(head, builtin_heads())
        .map(|h| match args {
            Some(a) => format!("; did you mean `{h}:{a}`?"),
            None => format!("; did you mean `{h}`?"),
        })
        .unwrap_or_default()
}

/// A fitted term rebuilt by deserialising its saved settings into `T`.
pub(crate) fn restore_as<T: serde::de::DeserializeOwned + Term + 'static>(
    name: &str,
    settings: &serde_json::Value,
) -> Result<Arc<dyn Term>, ModelError> {
    let t: T = serde_json::from_value(settings.clone()).map_err(|e| ModelError::BadTerm {
        term: name.to_string(),
        why: e.to_string(),
    })?;
    Ok(Arc::new(t))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codegen::{CContext, CPrecision};
    use crate::history::Feature;
    use crate::log::{ColumnMap, Log};
    use crate::model::data::FitData;
    use crate::numeric::rng::SimRng;

    /// Reference: the registry's heads. An unknown term gets the closest head with its
    /// arguments kept, and the message lists every head whole, within the shortest message
    /// limit (the full syntax list was cut mid-word there).
    #[test]
    fn an_unknown_term_gets_a_did_you_mean_and_every_head_whole() {
        let e = crate::model::ModelSpec::parse("poly2,dahll").unwrap_err();
        let m = crate::io::message(&e);
        assert!(
            m.starts_with("unknown term `dahll`; did you mean `dahl`?"),
            "{m}"
        );
        for b in BUILTINS.iter().filter(|b| b.syntax.is_some()) {
            assert!(
                m.contains(&format!(" {},", b.head)) || m.contains(&format!(" {};", b.head)),
                "{} in {m}",
                b.head
            );
        }
        assert!(!m.contains('…'), "{m}");
        let e = crate::model::ModelSpec::parse("stribek:velocity").unwrap_err();
        assert!(
            e.to_string().contains("did you mean `stribeck:velocity`?"),
            "{e}"
        );
        let e = crate::model::ModelSpec::parse("qqqq").unwrap_err();
        assert!(!e.to_string().contains("did you mean"), "{e}");
        let e = crate::model::ModelSpec::preset("calibraton").unwrap_err();
        assert!(e.to_string().contains("did you mean `calibration`?"), "{e}");
    }

    /// A random seek log with a covariate `temp_c`.
    fn log() -> Log {
        let mut rng = SimRng::new(7);
        let mut text = String::from("time_s,track,bias,temp_c\n");
        let mut x = 500.0;
        for i in 0..400 {
            x = (x + (rng.below(201) as f64) - 100.0).clamp(0.0, 1000.0);
            let v = 20.0 + rng.below(1000) as f64 / 100.0;
            text += &format!("{i},{x},{},{v}\n", rng.below(100));
        }
        Log::from_reader("r.csv", text.as_bytes(), &ColumnMap::default()).unwrap()
    }

    /// A spec text of the row `b`: its head with the arguments its syntax asks for.
    fn example(b: &BuiltinTerm) -> String {
        let syntax = b.syntax.unwrap_or(b.head);
        match syntax.matches(':').count() {
            _ if syntax.contains("COL:TERM") => format!("{}:temp_c:direction", b.head),
            _ if syntax.contains("A:B") => format!("{}:temp_c:position", b.head),
            _ if syntax.contains(":NAME") || syntax.contains(":COL") => {
                format!("{}:temp_c", b.head)
            }
            _ if syntax.contains(":FEATURE") => format!("{}:dwell_s", b.head),
            _ => b.head.to_string(),
        }
    }

    /// Row `b`'s [`example`] parsed by the row and prepared on `data`: its text and its term.
    fn prepared_example(
        b: &BuiltinTerm,
        data: &FitData<'_>,
    ) -> (String, Arc<dyn crate::model::term::Term>) {
        let text = example(b);
        let spec = (b.parse)(&TermText::new(&text)).unwrap_or_else(|e| panic!("{text}: {e}"));
        let term = spec.prepare(data).unwrap_or_else(|e| panic!("{text}: {e}"));
        (text, term)
    }

    /// Every registry row's term, prepared on a log, either writes itself as C (the rows that
    /// say so) or refuses, and then the export names it: its name has the row's head. A row
    /// whose flag disagrees with its term's `export_c` fails here: fix the row's `exports_c()`
    /// or the term's `Term::export_c`.
    #[test]
    fn every_term_exports_to_c_or_refuses_by_name() {
        let log = log();
        let data = FitData::new(&log);
        let ctx = CContext::new(CPrecision::Float64);
        for b in BUILTINS {
            let (text, term) = prepared_example(b, &data);
            let c = term.export_c(&ctx);
            assert_eq!(
                c.is_some(),
                b.exports_c,
                "{text}: export_c vs the row's exports_c"
            );
            if c.is_none() {
                assert_eq!(head(&term.name()), b.head, "{text}: refused under its name");
            }
        }
    }

    /// Every registry row's term, prepared on a log, says in `TermCaps::searches_itself`
    /// whether it has its own search (`Term::search` answers): a warm-started refit
    /// (`crate::fit::fit_sharing`'s `warm`) leaves such a term to it and searches the others by
    /// golden section near a value, which for a term with its own search (two parameters, a
    /// scan) would be wrong. The search is asked with the log's bias as the residual and a constant
    /// RSS: the test asks whether the term searches, not what it finds.
    #[test]
    fn every_term_with_its_own_search_says_so() {
        use crate::model::term::SearchContext;
        let log = log();
        let data = FitData::new(&log);
        let residual: Vec<f64> = (0..log.len()).filter_map(|i| log.bias(i)).collect();
        let residual_fn = || -> &[f64] { &residual };
        let rss = |_: &Arc<dyn crate::model::term::Term>| 1.0;
        let ctx = SearchContext::new(&data, &residual_fn, &rss, residual.len() - 3);
        let mut own = Vec::new();
        for b in BUILTINS {
            let (text, term) = prepared_example(b, &data);
            let searches = term.search(&ctx).is_some();
            assert_eq!(
                searches,
                term.caps().searches_itself,
                "{text}: Term::search vs TermCaps::searches_itself"
            );
            if searches {
                own.push(b.head);
            }
        }
        assert_eq!(
            own,
            ["preisach", "bump", "step"],
            "the terms with their own search"
        );
    }

    /// Within each pattern the ranks of the terms that answer it are distinct (the candidate
    /// order is theirs alone).
    #[test]
    fn answer_ranks_are_distinct_per_cue() {
        let mut cues = Vec::new();
        for f in Feature::ALL {
            cues.extend([Cue::Feature(f, false), Cue::Feature(f, true)]);
        }
        for law in [Law::OddLinear, Law::Velocity, Law::Linear, Law::Other] {
            cues.extend([
                Cue::Covariate(law, false),
                Cue::Covariate(law, true),
                Cue::DerivedVelocity(law),
            ]);
        }
        cues.extend([
            Cue::SummedMemory(false),
            Cue::SummedMemory(true),
            Cue::Lagged,
        ]);
        for cue in cues {
            let mut ranks: Vec<u8> = BUILTINS
                .iter()
                .filter_map(|b| (b.answers)(cue).map(|a| a.rank))
                .collect();
            let n = ranks.len();
            ranks.sort_unstable();
            ranks.dedup();
            assert_eq!(ranks.len(), n, "{cue:?}");
        }
    }
}
