//! How the domain values in `eval.json`, protocols, `registration.json` and `results.json` are
//! written: by their names, each spelled by the one type that owns it (a task by
//! [`SceneKind`], a method by [`Method`], ...), so that these files hold no spelling of their
//! own. `#[serde(with = "crate::by_name")]` on a field of a [`ByName`] type (and
//! `with = "crate::by_name::list"` on a `Vec` of one) writes its name with `Display` and reads
//! it back with [`ByName::from_name`], whose error names the value and what is allowed.

use std::fmt::Display;

use dips_kernel::diffusion::{SamplerConfig, SamplingMethod};
use dips_kernel::search::CostToCome;
use dips_onnx::EngineKind;
use dips_planning::online::{Method, SearchDepth};
use dips_world::scenes::SceneKind;
use serde::de::Error as _;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// A value written by its name: `Display` writes the name, [`ByName::from_name`] reads it,
/// through the type's own `FromStr` for every type but [`SamplingMethod`], whose names the
/// `FromStr` of the sampler it belongs to ([`SamplerConfig`]) reads.
pub trait ByName: Display + Sized {
    /// The value a name stands for; the error names the value and the names allowed.
    fn from_name(name: &str) -> Result<Self, String>;
}

/// [`ByName`] through the type's own `FromStr`, whose error already names the value and the
/// names allowed ([`dips_kernel::name::UnknownValue`]).
macro_rules! by_from_str {
    ($($t:ty),* $(,)?) => {$(
        impl ByName for $t {
            fn from_name(name: &str) -> Result<Self, String> {
                name.parse().map_err(|e| format!("{e}"))
            }
        }
    )*};
}

by_from_str!(SceneKind, Method, CostToCome, SearchDepth, EngineKind);

impl ByName for SamplingMethod {
    /// The method of the sampler the name stands for ([`SamplerConfig`]'s `FromStr`, which
    /// reads what `SamplingMethod`'s `Display` writes).
    fn from_name(name: &str) -> Result<Self, String> {
        name.parse::<SamplerConfig>()
            .map(|s| s.method)
            .map_err(|e| format!("unknown sampler `{name}`: {e}"))
    }
}

/// Write `value` as its name.
pub fn serialize<T: ByName, S: Serializer>(value: &T, serializer: S) -> Result<S::Ok, S::Error> {
    serializer.collect_str(value)
}

/// Read a value from its name; the error names the value and what is allowed.
pub fn deserialize<'de, T: ByName, D: Deserializer<'de>>(deserializer: D) -> Result<T, D::Error> {
    let name = String::deserialize(deserializer)?;
    T::from_name(&name).map_err(D::Error::custom)
}

/// A value serialized by its name: the element of [`list`].
struct Named<T>(T);

impl<T: ByName> Serialize for Named<&T> {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serialize(self.0, serializer)
    }
}

impl<'de, T: ByName> Deserialize<'de> for Named<T> {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        deserialize(deserializer).map(Named)
    }
}

/// A list of values written by their names (`#[serde(with = "crate::by_name::list")]`).
pub mod list {
    use super::*;

    /// Write `values` as a list of their names.
    pub fn serialize<T: ByName, S: Serializer>(
        values: &[T],
        serializer: S,
    ) -> Result<S::Ok, S::Error> {
        serializer.collect_seq(values.iter().map(Named))
    }

    /// Read a list of values from their names; the error names the first bad one and what is
    /// allowed.
    pub fn deserialize<'de, T: ByName, D: Deserializer<'de>>(
        deserializer: D,
    ) -> Result<Vec<T>, D::Error> {
        let named = Vec::<Named<T>>::deserialize(deserializer)?;
        Ok(named.into_iter().map(|n| n.0).collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, PartialEq, Serialize, Deserialize)]
    struct Fields {
        #[serde(with = "crate::by_name")]
        task: SceneKind,
        #[serde(with = "crate::by_name")]
        sampler: SamplingMethod,
        #[serde(with = "crate::by_name::list")]
        methods: Vec<Method>,
    }

    #[test]
    fn values_are_written_by_their_names_and_read_back() {
        let text = r#"{"task":"card","sampler":"ddim:8:0.5","methods":["dips","dips-k1"]}"#;
        let f: Fields = serde_json::from_str(text).unwrap();
        assert_eq!(f.task, SceneKind::Card);
        assert_eq!(f.sampler, SamplingMethod::Ddim { steps: 8, eta: 0.5 });
        assert_eq!(f.methods, [Method::Dips, Method::DipsK1]);
        assert_eq!(serde_json::to_string(&f).unwrap(), text);
    }

    #[test]
    fn a_bad_name_is_named_with_what_is_allowed() {
        let err = |text: &str| {
            serde_json::from_str::<Fields>(text)
                .unwrap_err()
                .to_string()
        };
        let e = err(r#"{"task":"pen","sampler":"ddpm","methods":[]}"#);
        assert!(
            e.contains("unknown task `pen` (expected screwdriver or card)"),
            "{e}"
        );
        let e = err(r#"{"task":"card","sampler":"ddim","methods":[]}"#);
        assert!(e.contains("unknown sampler `ddim`: expected `ddpm`"), "{e}");
        let e = err(r#"{"task":"card","sampler":"ddpm","methods":["dips","dipz"]}"#);
        assert!(e.contains("unknown method `dipz` (expected dips, "), "{e}");
    }
}
