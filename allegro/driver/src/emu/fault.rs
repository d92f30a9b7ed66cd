//! [`Fault`]'s text form (`silence@2`, `silence@0.5`, `garbage`, `hot@3`), as the hand spec's
//! `fault=` option writes it: parsed with [`FromStr`], written back with [`Display`].

use std::fmt;
use std::str::FromStr;
use std::time::Duration;

use super::Fault;

/// The forms a fault may take, as error messages list them.
pub const FAULT_FORMS: &str = "silence@<seconds>, garbage, hot@<seconds>";

/// Text that is not a [`Fault`].
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum FaultParseError {
    /// No fault has this name.
    #[error("unknown fault `{text}` (allowed: {FAULT_FORMS})")]
    Unknown {
        /// The text given.
        text: String,
    },
    /// A timed fault without its time, or a time where none belongs.
    #[error("fault `{text}` is malformed (allowed: {FAULT_FORMS})")]
    Form {
        /// The text given.
        text: String,
    },
    /// The time is not a finite, non-negative number of seconds.
    #[error(
        "fault `{text}`: `{time}` is not a time in seconds (a finite number ≥ 0; allowed: \
         {FAULT_FORMS})"
    )]
    Time {
        /// The text given.
        text: String,
        /// Its time part.
        time: String,
    },
}

impl FromStr for Fault {
    type Err = FaultParseError;

    /// `silence@<s>`, `garbage` or `hot@<s>`, seconds after the servo first comes on
    /// (surrounding whitespace ignored, names in lower case).
    fn from_str(s: &str) -> Result<Fault, FaultParseError> {
        let text = s.trim();
        let (name, time) = match text.split_once('@') {
            Some((n, t)) => (n, Some(t)),
            None => (text, None),
        };
        let at = |time: Option<&str>| -> Result<Duration, FaultParseError> {
            let time = time.ok_or_else(|| FaultParseError::Form { text: text.into() })?;
            let bad = || FaultParseError::Time {
                text: text.into(),
                time: time.into(),
            };
            let secs: f64 = time.trim().parse().map_err(|_| bad())?;
            Duration::try_from_secs_f64(secs).map_err(|_| bad())
        };
        match name {
            "silence" => Ok(Fault::SilenceAt(at(time)?)),
            "hot" => Ok(Fault::HotAt(at(time)?)),
            "garbage" if time.is_none() => Ok(Fault::Garbage),
            "garbage" => Err(FaultParseError::Form { text: text.into() }),
            _ => Err(FaultParseError::Unknown { text: text.into() }),
        }
    }
}

impl fmt::Display for Fault {
    /// The form [`FromStr`] reads: `silence@2`, `silence@0.5`, `garbage`, `hot@3`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Fault::SilenceAt(t) => write!(f, "silence@{}", t.as_secs_f64()),
            Fault::Garbage => f.write_str("garbage"),
            Fault::HotAt(t) => write!(f, "hot@{}", t.as_secs_f64()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn faults_parse_and_print_back() {
        for (text, fault) in [
            ("silence@2", Fault::SilenceAt(Duration::from_secs(2))),
            ("silence@0.5", Fault::SilenceAt(Duration::from_millis(500))),
            ("garbage", Fault::Garbage),
            ("hot@3", Fault::HotAt(Duration::from_secs(3))),
            ("hot@0", Fault::HotAt(Duration::ZERO)),
        ] {
            assert_eq!(text.parse::<Fault>(), Ok(fault), "{text}");
            assert_eq!(fault.to_string(), text);
        }
        assert_eq!(
            " silence@0.25 ".parse::<Fault>(),
            Ok(Fault::SilenceAt(Duration::from_millis(250)))
        );
    }

    #[test]
    fn bad_faults_name_the_text_and_the_allowed_forms() {
        for (text, want) in [
            ("loud@2", "unknown fault `loud@2`"),
            ("silence", "fault `silence` is malformed"),
            ("garbage@1", "fault `garbage@1` is malformed"),
            ("hot@x", "`x` is not a time"),
            ("hot@-1", "`-1` is not a time"),
            ("silence@inf", "`inf` is not a time"),
            ("silence@NaN", "`NaN` is not a time"),
            ("", "unknown fault ``"),
        ] {
            let e = text.parse::<Fault>().unwrap_err().to_string();
            assert!(e.contains(want), "{text}: {e}");
            assert!(e.contains(FAULT_FORMS), "{text}: {e}");
        }
    }
}
