//! Whole-number fields of the scene format. JSON has one number type:
//! `64`, `64.0` and `6.4e1` are the same value, so each is read as 64. A
//! fraction, a value outside the field's range or anything but a number is
//! refused with the range in the message (serde's own integer reading
//! refused `64.0` and said "expected u32").

use std::fmt;

use serde::Deserializer;
use serde::de::{Error, Unexpected, Visitor};

use super::scene_file::num;

/// The range of a whole-number field, and the unit its message names
/// (e.g. " pixels").
#[derive(Debug, Clone, Copy)]
pub struct WholeRange {
    pub lo: u64,
    pub hi: u64,
    pub unit: &'static str,
}

impl WholeRange {
    pub const fn new(lo: u64, hi: u64, unit: &'static str) -> WholeRange {
        WholeRange { lo, hi, unit }
    }

    /// "`value` is out of range, expected lo..=hi unit": one wording for
    /// the reader and the validation of scenes built in code.
    pub fn out_of_range(&self, value: impl fmt::Display) -> String {
        format!("{value} is out of range, expected {self}")
    }
}

impl fmt::Display for WholeRange {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        if self.lo == self.hi {
            write!(f, "{}{}", self.lo, self.unit)
        } else {
            write!(f, "{}..={}{}", self.lo, self.hi, self.unit)
        }
    }
}

/// Reads a whole number within `range` into `T` (which holds all of it).
pub fn deserialize_whole<'de, D, T>(d: D, range: WholeRange) -> Result<T, D::Error>
where
    D: Deserializer<'de>,
    T: TryFrom<u64>,
{
    let v = d.deserialize_any(WholeVisitor { range })?;
    T::try_from(v).map_err(|_| D::Error::custom(range.out_of_range(v)))
}

struct WholeVisitor {
    range: WholeRange,
}

impl WholeVisitor {
    fn check<E: Error>(&self, v: u64) -> Result<u64, E> {
        if (self.range.lo..=self.range.hi).contains(&v) {
            Ok(v)
        } else {
            Err(E::custom(self.range.out_of_range(v)))
        }
    }
}

impl<'de> Visitor<'de> for WholeVisitor {
    type Value = u64;

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        write!(f, "a whole number in {}", self.range)
    }

    fn visit_u64<E: Error>(self, v: u64) -> Result<u64, E> {
        self.check(v)
    }

    fn visit_i64<E: Error>(self, v: i64) -> Result<u64, E> {
        match u64::try_from(v) {
            Ok(v) => self.check(v),
            Err(_) => Err(E::custom(self.range.out_of_range(v))),
        }
    }

    fn visit_f64<E: Error>(self, v: f64) -> Result<u64, E> {
        if v.fract() != 0.0 || !v.is_finite() {
            return Err(E::invalid_value(Unexpected::Float(v), &self));
        }
        // 2⁶⁴ is the first whole f64 beyond u64; a whole f64 below it
        // converts exactly.
        if (0.0..18_446_744_073_709_551_616.0).contains(&v) {
            self.check(v as u64)
        } else {
            Err(E::custom(self.range.out_of_range(num(v))))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(json: &str, lo: u64, hi: u64) -> Result<u32, String> {
        let mut de = serde_json::Deserializer::from_str(json);
        deserialize_whole::<_, u32>(&mut de, WholeRange::new(lo, hi, " pixels"))
            .map_err(|e| e.to_string())
    }

    #[test]
    fn whole_numbers_in_any_spelling_are_read() {
        for json in ["64", "64.0", "6.4e1", "640e-1", "64E0"] {
            assert_eq!(read(json, 1, 100), Ok(64), "{json}");
        }
        assert_eq!(read("4294967295.0", 0, u64::MAX), Ok(u32::MAX));
    }

    #[test]
    fn fractions_ranges_and_other_types_are_refused_with_the_range() {
        let cases = [
            (
                "64.5",
                "invalid value: floating point `64.5`, expected a whole number in 1..=100 pixels",
            ),
            ("-1", "-1 is out of range, expected 1..=100 pixels"),
            ("0", "0 is out of range, expected 1..=100 pixels"),
            ("101", "101 is out of range, expected 1..=100 pixels"),
            ("1e300", "1e300 is out of range, expected 1..=100 pixels"),
            (
                "\"3\"",
                "invalid type: string \"3\", expected a whole number in 1..=100 pixels",
            ),
            (
                "null",
                "invalid type: null, expected a whole number in 1..=100 pixels",
            ),
        ];
        for (json, message) in cases {
            let e = read(json, 1, 100).unwrap_err();
            assert!(e.starts_with(message), "{json}: {e}");
        }
        // Within the range but beyond the field's type.
        let e = read("4294967296", 0, u64::MAX).unwrap_err();
        assert!(e.starts_with("4294967296 is out of range"), "{e}");
    }
}
