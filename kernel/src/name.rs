//! The error of the domain values' `FromStr` (a task, a cost-to-come form, a method, ...): the
//! one message that names the bad value and the allowed ones, kept without a heap.

use core::fmt;

/// The longest part of a bad value kept for the message (longer ones end in `…`).
pub const KEPT_CHARS: usize = 48;

/// A name that is none of a value's names: what kind of value, the name given (its first
/// [`KEPT_CHARS`] bytes, cut at a character boundary) and the names allowed. Its message reads
/// ``unknown task `pen` (expected screwdriver or card)``.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UnknownValue {
    what: &'static str,
    allowed: &'static [&'static str],
    given: heapless::String<KEPT_CHARS>,
    cut: bool,
}

impl UnknownValue {
    /// `given` is not one of `allowed`, the names of a `what` (`"task"`, `"method"`, ...).
    pub fn new(what: &'static str, given: &str, allowed: &'static [&'static str]) -> Self {
        let mut kept = heapless::String::new();
        let mut cut = false;
        for c in given.chars() {
            if kept.push(c).is_err() {
                cut = true;
                break;
            }
        }
        Self {
            what,
            allowed,
            given: kept,
            cut,
        }
    }

    /// What kind of value was asked for (`"task"`, `"method"`, ...).
    pub fn what(&self) -> &'static str {
        self.what
    }

    /// The name given (at most [`KEPT_CHARS`] bytes of it).
    pub fn given(&self) -> &str {
        &self.given
    }

    /// The names allowed.
    pub fn allowed(&self) -> &'static [&'static str] {
        self.allowed
    }

    /// Find `given` among `values` by `name`, or the error naming it and every name.
    pub fn find<T: Copy>(
        what: &'static str,
        given: &str,
        values: &[T],
        allowed: &'static [&'static str],
        name: impl Fn(T) -> &'static str,
    ) -> Result<T, Self> {
        values
            .iter()
            .copied()
            .find(|&v| name(v) == given)
            .ok_or_else(|| Self::new(what, given, allowed))
    }
}

impl fmt::Display for UnknownValue {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "unknown {} `{}", self.what, self.given)?;
        if self.cut {
            f.write_str("…")?;
        }
        f.write_str("` (expected ")?;
        let n = self.allowed.len();
        for (i, name) in self.allowed.iter().enumerate() {
            match i {
                0 => {}
                _ if i + 1 == n && n == 2 => f.write_str(" or ")?,
                _ if i + 1 == n => f.write_str(", or ")?,
                _ => f.write_str(", ")?,
            }
            f.write_str(name)?;
        }
        f.write_str(")")
    }
}

impl core::error::Error for UnknownValue {}

#[cfg(test)]
mod tests {
    use super::*;
    use std::string::ToString;

    #[test]
    fn the_message_names_the_value_and_the_allowed_ones() {
        let e = UnknownValue::new("task", "pen", &["screwdriver", "card"]);
        assert_eq!(
            e.to_string(),
            "unknown task `pen` (expected screwdriver or card)"
        );
        let e = UnknownValue::new("form", "x", &["a", "b", "c"]);
        assert_eq!(e.to_string(), "unknown form `x` (expected a, b, or c)");
        let long = "é".repeat(40);
        let e = UnknownValue::new("task", &long, &["card"]);
        assert_eq!(e.given(), "é".repeat(24));
        assert!(e.to_string().contains("…`"));
    }
}
