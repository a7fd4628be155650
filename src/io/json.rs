//! The one JSON writer: every JSON text biasctl writes (model files, `--json` output,
//! `diagnosis.json`, `discover.json`, the report's JSON files) is made by [`to_string_pretty`].
//!
//! serde_json writes a `NaN` or an infinity as `null`, which a reader cannot tell from a value
//! that is absent. [`to_string_pretty`] first walks the value with a serializer that writes
//! nothing and only looks at every number ([`check`]): a non-finite `f32`/`f64` is refused as
//! [`NonFinite`] naming its key path (`terms[2].coefficients[0]`, `histogram.mean`), and
//! nothing is written. An `Option` that is `None` is still written as `null`: that is a value
//! that is absent, not a number that overflowed.

use super::{NonFinite, OutputError};
use serde::ser::{self, Serialize};
use std::fmt;

/// `value` as pretty-printed JSON, or [`OutputError::NonFinite`] naming the key path of the
/// first non-finite number (then nothing is produced).
pub fn to_string_pretty<T: Serialize + ?Sized>(value: &T) -> Result<String, OutputError> {
    check(value)?;
    serde_json::to_string_pretty(value).map_err(|e| {
        OutputError::NonFinite(NonFinite {
            what: format!("JSON output ({})", super::quote(&e.to_string())),
            value: f64::NAN,
        })
    })
}

/// Checks that every number `value` serializes is finite; the error names the key path of the
/// first one that is not (`$` is the top level).
pub(crate) fn check<T: Serialize + ?Sized>(value: &T) -> Result<(), NonFinite> {
    let mut walker = Walker { path: Vec::new() };
    match value.serialize(&mut walker) {
        Ok(()) => Ok(()),
        Err(Stop::NonFinite(e)) => Err(e),
        // A value serde cannot serialize at all is serde_json's error to report.
        Err(Stop::Custom) => Ok(()),
    }
}

/// Why the walk stopped.
#[derive(Debug)]
enum Stop {
    NonFinite(NonFinite),
    Custom,
}

impl fmt::Display for Stop {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Stop::NonFinite(e) => e.fmt(f),
            Stop::Custom => f.write_str("not serializable"),
        }
    }
}

impl std::error::Error for Stop {}

impl ser::Error for Stop {
    fn custom<M: fmt::Display>(_msg: M) -> Self {
        Stop::Custom
    }
}

/// One step of a key path.
#[derive(Debug, Clone)]
enum Step {
    Key(String),
    Index(usize),
}

/// A serializer that writes nothing and checks every float, keeping the key path.
struct Walker {
    path: Vec<Step>,
}

impl Walker {
    fn path_text(&self) -> String {
        let mut s = String::new();
        for step in &self.path {
            match step {
                Step::Key(k) if s.is_empty() => s.push_str(k),
                Step::Key(k) => {
                    s.push('.');
                    s.push_str(k);
                }
                Step::Index(i) => s.push_str(&format!("[{i}]")),
            }
        }
        if s.is_empty() { "$".into() } else { s }
    }

    fn float(&mut self, v: f64) -> Result<(), Stop> {
        if v.is_finite() {
            Ok(())
        } else {
            Err(Stop::NonFinite(NonFinite {
                what: format!("JSON key `{}`", super::quote(&self.path_text())),
                value: v,
            }))
        }
    }

    fn nested<T: Serialize + ?Sized>(&mut self, step: Step, value: &T) -> Result<(), Stop> {
        self.path.push(step);
        let r = value.serialize(&mut *self);
        self.path.pop();
        r
    }
}

/// A collection being walked: the index of the next element, the key of the next map value.
struct Compound<'a> {
    walker: &'a mut Walker,
    index: usize,
    key: Option<String>,
}

impl Compound<'_> {
    fn element<T: Serialize + ?Sized>(&mut self, value: &T) -> Result<(), Stop> {
        let i = self.index;
        self.index += 1;
        self.walker.nested(Step::Index(i), value)
    }
}

macro_rules! ignore {
    ($($name:ident($t:ty)),*) => {
        $(fn $name(self, _v: $t) -> Result<(), Stop> { Ok(()) })*
    };
}

impl<'a> ser::Serializer for &'a mut Walker {
    type Ok = ();
    type Error = Stop;
    type SerializeSeq = Compound<'a>;
    type SerializeTuple = Compound<'a>;
    type SerializeTupleStruct = Compound<'a>;
    type SerializeTupleVariant = Compound<'a>;
    type SerializeMap = Compound<'a>;
    type SerializeStruct = Compound<'a>;
    type SerializeStructVariant = Compound<'a>;

    ignore!(
        serialize_bool(bool),
        serialize_i8(i8),
        serialize_i16(i16),
        serialize_i32(i32),
        serialize_i64(i64),
        serialize_i128(i128),
        serialize_u8(u8),
        serialize_u16(u16),
        serialize_u32(u32),
        serialize_u64(u64),
        serialize_u128(u128),
        serialize_char(char),
        serialize_str(&str),
        serialize_bytes(&[u8])
    );

    fn serialize_f32(self, v: f32) -> Result<(), Stop> {
        self.float(f64::from(v))
    }
    fn serialize_f64(self, v: f64) -> Result<(), Stop> {
        self.float(v)
    }
    fn serialize_none(self) -> Result<(), Stop> {
        Ok(())
    }
    fn serialize_some<T: Serialize + ?Sized>(self, value: &T) -> Result<(), Stop> {
        value.serialize(self)
    }
    fn serialize_unit(self) -> Result<(), Stop> {
        Ok(())
    }
    fn serialize_unit_struct(self, _name: &'static str) -> Result<(), Stop> {
        Ok(())
    }
    fn serialize_unit_variant(
        self,
        _n: &'static str,
        _i: u32,
        _v: &'static str,
    ) -> Result<(), Stop> {
        Ok(())
    }
    fn serialize_newtype_struct<T: Serialize + ?Sized>(
        self,
        _name: &'static str,
        value: &T,
    ) -> Result<(), Stop> {
        value.serialize(self)
    }
    fn serialize_newtype_variant<T: Serialize + ?Sized>(
        self,
        _name: &'static str,
        _i: u32,
        variant: &'static str,
        value: &T,
    ) -> Result<(), Stop> {
        self.nested(Step::Key(variant.into()), value)
    }
    fn serialize_seq(self, _len: Option<usize>) -> Result<Compound<'a>, Stop> {
        Ok(self.compound())
    }
    fn serialize_tuple(self, _len: usize) -> Result<Compound<'a>, Stop> {
        Ok(self.compound())
    }
    fn serialize_tuple_struct(self, _n: &'static str, _len: usize) -> Result<Compound<'a>, Stop> {
        Ok(self.compound())
    }
    fn serialize_tuple_variant(
        self,
        _n: &'static str,
        _i: u32,
        _v: &'static str,
        _len: usize,
    ) -> Result<Compound<'a>, Stop> {
        Ok(self.compound())
    }
    fn serialize_map(self, _len: Option<usize>) -> Result<Compound<'a>, Stop> {
        Ok(self.compound())
    }
    fn serialize_struct(self, _n: &'static str, _len: usize) -> Result<Compound<'a>, Stop> {
        Ok(self.compound())
    }
    fn serialize_struct_variant(
        self,
        _n: &'static str,
        _i: u32,
        _v: &'static str,
        _len: usize,
    ) -> Result<Compound<'a>, Stop> {
        Ok(self.compound())
    }
}

impl Walker {
    fn compound(&mut self) -> Compound<'_> {
        Compound {
            walker: self,
            index: 0,
            key: None,
        }
    }
}

macro_rules! seq_like {
    ($($tr:ident :: $m:ident),*) => {
        $(impl ser::$tr for Compound<'_> {
            type Ok = ();
            type Error = Stop;
            fn $m<T: Serialize + ?Sized>(&mut self, value: &T) -> Result<(), Stop> {
                self.element(value)
            }
            fn end(self) -> Result<(), Stop> {
                Ok(())
            }
        })*
    };
}

seq_like!(
    SerializeSeq::serialize_element,
    SerializeTuple::serialize_element,
    SerializeTupleStruct::serialize_field,
    SerializeTupleVariant::serialize_field
);

macro_rules! struct_like {
    ($($tr:ident),*) => {
        $(impl ser::$tr for Compound<'_> {
            type Ok = ();
            type Error = Stop;
            fn serialize_field<T: Serialize + ?Sized>(
                &mut self,
                key: &'static str,
                value: &T,
            ) -> Result<(), Stop> {
                self.walker.nested(Step::Key(key.into()), value)
            }
            fn end(self) -> Result<(), Stop> {
                Ok(())
            }
        })*
    };
}

struct_like!(SerializeStruct, SerializeStructVariant);

impl ser::SerializeMap for Compound<'_> {
    type Ok = ();
    type Error = Stop;
    fn serialize_key<T: Serialize + ?Sized>(&mut self, key: &T) -> Result<(), Stop> {
        // JSON keys are strings (serde_json also accepts numbers and writes them quoted).
        let text = serde_json::to_string(key).unwrap_or_default();
        self.key = Some(text.trim_matches('"').to_string());
        Ok(())
    }
    fn serialize_value<T: Serialize + ?Sized>(&mut self, value: &T) -> Result<(), Stop> {
        let key = self.key.take().unwrap_or_default();
        self.walker.nested(Step::Key(key), value)
    }
    fn end(self) -> Result<(), Stop> {
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeMap;

    #[derive(serde::Serialize)]
    struct Term {
        name: String,
        coefficients: Vec<f64>,
        rate: Option<f64>,
    }

    #[derive(serde::Serialize)]
    struct Model {
        terms: Vec<Term>,
        stats: BTreeMap<String, f32>,
        tuple: (u8, f64),
    }

    fn model(bad: impl Fn(&mut Model)) -> Model {
        let mut m = Model {
            terms: vec![
                Term {
                    name: "poly2".into(),
                    coefficients: vec![1.0, -2.5e300, 3e-300],
                    rate: None,
                },
                Term {
                    name: "dahl".into(),
                    coefficients: vec![0.5],
                    rate: Some(0.9),
                },
            ],
            stats: BTreeMap::from([("mean".to_string(), 1.5f32)]),
            tuple: (1, 2.0),
        };
        bad(&mut m);
        m
    }

    /// Reference: serde_json's own output for the finite value (byte for byte), and the key
    /// path written out by hand for each planted non-finite number.
    #[test]
    fn finite_values_are_written_as_serde_json_writes_them_and_non_finite_ones_name_their_key() {
        let ok = model(|_| {});
        assert_eq!(
            to_string_pretty(&ok).unwrap(),
            serde_json::to_string_pretty(&ok).unwrap()
        );
        // `None` stays `null`: an absent value, not an overflow.
        assert!(to_string_pretty(&ok).unwrap().contains("\"rate\": null"));
        type Plant = fn(&mut Model);
        let cases: [(Plant, &str, f64); 5] = [
            (
                |m| m.terms[0].coefficients[1] = f64::INFINITY,
                "terms[0].coefficients[1]",
                f64::INFINITY,
            ),
            (
                |m| m.terms[1].rate = Some(f64::NAN),
                "terms[1].rate",
                f64::NAN,
            ),
            (
                |m| {
                    m.stats.insert("std".into(), f32::NEG_INFINITY);
                },
                "stats.std",
                f64::NEG_INFINITY,
            ),
            (|m| m.tuple.1 = f64::NAN, "tuple[1]", f64::NAN),
            (
                |m| m.terms[1].coefficients[0] = -f64::INFINITY,
                "terms[1].coefficients[0]",
                f64::NEG_INFINITY,
            ),
        ];
        for (plant, path, value) in cases {
            let m = model(plant);
            // serde_json alone would write `null` here.
            assert!(serde_json::to_string_pretty(&m).unwrap().contains("null"));
            let e = to_string_pretty(&m).unwrap_err().to_string();
            assert!(e.contains(&format!("JSON key `{path}`")), "{e}");
            assert!(e.contains(&format!("is {value}")), "{e}");
        }
        let e = check(&f64::NAN).unwrap_err();
        assert_eq!(e.what, "JSON key `$`");
    }
}
