//! The built-in terms, one file per term, and the parser of term spec strings.

pub mod bins;
pub mod covariate;
pub mod dahl;
pub mod direction;
pub mod drift;
pub mod intercept;
pub mod knots;
pub mod memory;
pub mod play;
pub mod poly;
pub mod seek;
pub mod table;

use super::term::{Term, TermSpec};
use super::{ModelError, SpecError};
use std::sync::Arc;

/// The names of the built-in terms, for messages.
pub const BUILTIN_NAMES: &str = "poly2, table[:SPACING], direction, seek[:KNOTS], memory[:KNOTS], drift[:ALPHA], dahl, dahl:N, play[:N], col:NAME, bins:FEATURE[:KNOTS], dbins:FEATURE[:KNOTS]";

/// Parses one built-in term spec (`poly2`, `table:50`, `dahl:4`, `col:temp_c`, `bins:dwell_s`,
/// `dbins:dwell_s:6`…).
pub fn parse_term(text: &str) -> Result<Arc<dyn TermSpec>, SpecError> {
    let text = text.trim();
    let (head, arg) = match text.split_once(':') {
        Some((h, a)) => (h, Some(a)),
        None => (text, None),
    };
    let bad = |why: String| SpecError::BadArgument {
        term: text.to_string(),
        why,
    };
    let count = |a: &str, what: &str, max: usize| -> Result<usize, SpecError> {
        match a.parse::<usize>() {
            Ok(n) if (1..=max).contains(&n) => Ok(n),
            _ => Err(bad(format!(
                "{what} must be an integer from 1 to {max}, got `{a}`"
            ))),
        }
    };
    let no_arg = |spec: Arc<dyn TermSpec>| match arg {
        None => Ok(spec),
        Some(a) => Err(bad(format!("`{head}` takes no argument, got `{a}`"))),
    };
    match head {
        "poly2" => no_arg(Arc::new(poly::Poly2Spec)),
        "direction" => no_arg(Arc::new(direction::DirectionSpec)),
        "intercept" => no_arg(Arc::new(intercept::InterceptSpec)),
        "table" => {
            let spacing = match arg {
                None => None,
                Some(a) => match a.parse::<f64>() {
                    Ok(h) if h.is_finite() && h > 0.0 => Some(h),
                    _ => {
                        return Err(bad(format!(
                            "knot spacing must be a positive number (in the log's position unit), got `{a}`"
                        )));
                    }
                },
            };
            Ok(Arc::new(table::TableSpec { spacing }))
        }
        "seek" => Ok(Arc::new(seek::SeekSpec {
            knots: arg
                .map(|a| count(a, "the number of knots", 32))
                .transpose()?
                .unwrap_or(seek::DEFAULT_KNOTS),
        })),
        "memory" => Ok(Arc::new(memory::MemorySpec {
            knots: arg
                .map(|a| count(a, "the number of knots", 32))
                .transpose()?
                .unwrap_or(memory::DEFAULT_KNOTS),
        })),
        "drift" => {
            let alpha = match arg {
                None => None,
                Some(a) => match a.parse::<f64>() {
                    Ok(v) if v > 0.0 && v <= 1.0 => Some(v),
                    _ => {
                        return Err(bad(format!(
                            "the forgetting factor must be in (0, 1], got `{a}`"
                        )));
                    }
                },
            };
            Ok(Arc::new(drift::DriftSpec { alpha }))
        }
        "dahl" => Ok(Arc::new(dahl::DahlSpec {
            elements: arg
                .map(|a| count(a, "the number of Dahl elements", 16))
                .transpose()?,
        })),
        "play" => Ok(Arc::new(play::PlaySpec {
            elements: arg
                .map(|a| count(a, "the number of play elements", 256))
                .transpose()?
                .unwrap_or(play::DEFAULT_ELEMENTS),
        })),
        "col" => match arg {
            Some(name) if !name.is_empty() => Ok(Arc::new(covariate::ColSpec {
                column: name.to_string(),
            })),
            _ => Err(bad("`col` needs a column name: `col:NAME`".into())),
        },
        "bins" | "dbins" => {
            let Some(a) = arg.filter(|a| !a.is_empty()) else {
                return Err(bad(format!(
                    "`{head}` needs a feature or column name: `{head}:FEATURE`"
                )));
            };
            let (source, knots) = match a.rsplit_once(':') {
                Some((s, k)) => (s, count(k, "the number of knots", 32)?),
                None => (a, bins::DEFAULT_KNOTS),
            };
            if source.is_empty() {
                return Err(bad(format!(
                    "`{head}` needs a feature or column name: `{head}:FEATURE`"
                )));
            }
            Ok(Arc::new(bins::BinsSpec::new(
                source,
                knots,
                head == "dbins",
            )))
        }
        _ => Err(SpecError::UnknownTerm {
            term: text.to_string(),
        }),
    }
}

/// Rebuilds a built-in fitted term from its name and saved settings (the model file).
pub fn restore_term(name: &str, settings: &serde_json::Value) -> Result<Arc<dyn Term>, ModelError> {
    fn de<T: serde::de::DeserializeOwned>(
        name: &str,
        v: &serde_json::Value,
    ) -> Result<T, ModelError> {
        serde_json::from_value(v.clone()).map_err(|e| ModelError::BadTerm {
            term: name.to_string(),
            why: e.to_string(),
        })
    }
    let head = name.split(':').next().unwrap_or("");
    Ok(match head {
        "intercept" => Arc::new(intercept::InterceptTerm),
        "poly2" => Arc::new(de::<poly::Poly2Term>(name, settings)?),
        "direction" => Arc::new(direction::DirectionTerm),
        "table" => Arc::new(de::<table::TableTerm>(name, settings)?),
        "seek" => Arc::new(de::<seek::SeekTerm>(name, settings)?),
        "memory" => Arc::new(de::<memory::MemoryTerm>(name, settings)?),
        "drift" => Arc::new(de::<drift::DriftTerm>(name, settings)?),
        "dahl" => Arc::new(de::<dahl::DahlTerm>(name, settings)?),
        "play" => Arc::new(de::<play::PlayTerm>(name, settings)?),
        "col" => Arc::new(de::<covariate::ColTerm>(name, settings)?),
        "bins" | "dbins" => Arc::new(bins::BinsTerm {
            by_direction: head == "dbins",
            ..de::<bins::BinsTerm>(name, settings)?
        }),
        _ => {
            return Err(ModelError::BadTerm {
                term: name.to_string(),
                why: "not a built-in term (load a model with user terms through FittedModel::load_with)".into(),
            });
        }
    })
}

/// Position of covariate `column` among `names`, or the error a model reports for it.
pub fn covariate_position(names: &[String], column: &str, term: &str) -> Result<usize, ModelError> {
    names
        .iter()
        .position(|n| n == column)
        .ok_or_else(|| ModelError::MissingCovariate {
            term: term.to_string(),
            column: column.to_string(),
            available: if names.is_empty() {
                "none".into()
            } else {
                names.join(", ")
            },
        })
}
