//! Filter settings, declared once per filter with [`filter_settings!`]: one struct whose
//! defaults are written in one place. From it come the command-line flags (`--kw`,
//! `--atrous-iterations`, ...), the `[filter.<name>]` table of a scene file, the settings an AOV
//! file records, and the `--explain` / report text. Everything between them is a TOML table:
//! defaults, then each layer (an AOV file's record, the scene file, the command line) overrides
//! key by key, and serde turns the result into the typed struct, naming any bad field.

use std::fmt::Write as _;

use anyhow::{Result, anyhow};
use serde::de::DeserializeOwned;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// One setting as the command line and reports see it.
#[derive(Debug)]
pub struct FieldDoc {
    /// The field name: the key in `[filter.<name>]`, and the flag `--<prefix><name>` with `_`
    /// written `-`.
    pub name: &'static str,
    /// The Rust type, for the value name in `--help`.
    pub ty: &'static str,
    /// The doc comment, line by line.
    pub doc: &'static [&'static str],
}

impl FieldDoc {
    /// The doc comment as one line.
    pub fn help(&self) -> String {
        self.doc
            .iter()
            .map(|l| l.trim())
            .collect::<Vec<_>>()
            .join(" ")
    }

    /// Takes no value on the command line (`--holes`, `--holes=false`).
    pub fn is_switch(&self) -> bool {
        matches!(self.ty, "bool" | "Auto<bool>")
    }

    /// The flag for a filter whose flags start with `prefix`.
    pub fn flag(&self, prefix: &str) -> String {
        format!("{prefix}{}", self.name.replace('_', "-"))
    }
}

/// What [`filter_settings!`] implements for a settings struct.
pub trait DeclaredSettings:
    Clone + std::fmt::Debug + Default + PartialEq + Serialize + DeserializeOwned + Send + Sync + 'static
{
    /// Prefix of the struct's command-line flags, e.g. `"atrous-"`.
    const FLAG_PREFIX: &'static str;
    fn fields() -> &'static [FieldDoc];
}

/// Declares a filter's settings struct: each field with its doc comment, type and default.
///
/// ```ignore
/// filter_settings! {
///     /// The box filter's settings.
///     pub struct BoxSettings, flags "box-" {
///         /// Half width of the box, pixels.
///         pub radius: u32 = 1,
///     }
/// }
/// ```
#[macro_export]
macro_rules! filter_settings {
    (
        $(#[doc = $doc:literal])*
        pub struct $name:ident, flags $prefix:literal {
            $(
                $(#[doc = $fdoc:literal])*
                pub $field:ident : $ty:ty = $default:expr
            ),* $(,)?
        }
    ) => {
        $(#[doc = $doc])*
        #[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
        #[serde(default, deny_unknown_fields)]
        pub struct $name {
            $( $(#[doc = $fdoc])* pub $field: $ty, )*
        }

        impl Default for $name {
            fn default() -> Self {
                $name { $( $field: $default, )* }
            }
        }

        impl $crate::filters::settings::DeclaredSettings for $name {
            const FLAG_PREFIX: &'static str = $prefix;
            fn fields() -> &'static [$crate::filters::settings::FieldDoc] {
                &[ $( $crate::filters::settings::FieldDoc {
                    name: stringify!($field),
                    ty: stringify!($ty),
                    doc: &[$($fdoc),*],
                } ),* ]
            }
        }
    };
}

/// A setting the filter chooses from the scene (or from its other settings) unless it is set:
/// `"auto"` in a file or on the command line, or the value.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Auto<T> {
    #[default]
    Auto,
    Set(T),
}

impl<T: Copy> Auto<T> {
    /// The value, or `auto` when the filter chooses.
    pub fn or(self, auto: T) -> T {
        match self {
            Auto::Auto => auto,
            Auto::Set(v) => v,
        }
    }

    pub fn is_auto(self) -> bool {
        matches!(self, Auto::Auto)
    }
}

impl<T: Serialize> Serialize for Auto<T> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            Auto::Auto => s.serialize_str("auto"),
            Auto::Set(v) => v.serialize(s),
        }
    }
}

impl<'de, T: Deserialize<'de>> Deserialize<'de> for Auto<T> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Repr<T> {
            Value(T),
            Word(String),
        }
        let expected = format!(
            "expected \"auto\" or a {}",
            short_type(std::any::type_name::<T>())
        );
        match Repr::<T>::deserialize(d) {
            Ok(Repr::Value(v)) => Ok(Auto::Set(v)),
            Ok(Repr::Word(w)) if w == "auto" => Ok(Auto::Auto),
            // A word T refuses: T's own reason (for an enum, the words it takes).
            Ok(Repr::Word(w)) => {
                let word = serde::de::value::StrDeserializer::<serde::de::value::Error>::new(&w);
                let why = T::deserialize(word).err().map(|e| format!(" ({e})"));
                Err(serde::de::Error::custom(
                    expected + &why.unwrap_or_default(),
                ))
            }
            _ => Err(serde::de::Error::custom(expected)),
        }
    }
}

fn short_type(name: &str) -> &str {
    name.rsplit("::").next().unwrap_or(name)
}

/// The typed settings as a TOML table (every field).
pub fn to_table<S: Serialize>(s: &S) -> toml::Table {
    toml::Table::try_from(s).expect("filter settings serialise to a TOML table")
}

/// Typed settings from a table; the error names the bad key and what it expects.
pub fn from_table<S: DeserializeOwned>(t: &toml::Table) -> Result<S> {
    t.clone()
        .try_into()
        .map_err(|e: toml::de::Error| anyhow!("{}", e.message().trim()))
}

/// `base` with every key of `over` replacing its own.
pub fn overlay(base: &mut toml::Table, over: &toml::Table) {
    for (k, v) in over {
        base.insert(k.clone(), v.clone());
    }
}

/// A command-line value as TOML, shaped like the field's default: a comma-separated list for an
/// array, else a TOML literal (number, boolean), else the text itself (a name, `auto`).
pub fn parse_flag_value(raw: &str, default: &toml::Value) -> toml::Value {
    fn scalar(raw: &str) -> toml::Value {
        let raw = raw.trim();
        if let Ok(t) = toml::from_str::<toml::Table>(&format!("v = {raw}"))
            && let Some(v) = t.get("v")
            && !v.is_table()
        {
            return v.clone();
        }
        if let Ok(x) = raw.parse::<f64>() {
            return toml::Value::Float(x);
        }
        toml::Value::String(raw.to_string())
    }
    match default {
        toml::Value::Array(_) => toml::Value::Array(raw.split(',').map(scalar).collect()),
        // A table of tables (stylized-shadows' per-light controls): an inline TOML table,
        // `--stylized-lights '{1 = {softness = [0.4, 0, 0]}}'`.
        toml::Value::Table(_) => toml::from_str::<toml::Table>(&format!("v = {raw}"))
            .ok()
            .and_then(|t| t.get("v").cloned())
            .unwrap_or_else(|| toml::Value::String(raw.to_string())),
        _ => scalar(raw),
    }
}

/// A value for people: floats in their shortest form as f32 when they are f32 values (as every
/// filter setting is), so 0.1 reads `0.1`, not `0.10000000149011612`.
pub fn display_value(v: &toml::Value) -> String {
    match v {
        toml::Value::Float(x) => {
            let f = *x as f32;
            if f as f64 == *x {
                let s = format!("{f}");
                if s.contains(['.', 'e', 'i', 'N']) {
                    s
                } else {
                    format!("{s}.0")
                }
            } else {
                format!("{x}")
            }
        }
        toml::Value::Array(a) => format!(
            "[{}]",
            a.iter().map(display_value).collect::<Vec<_>>().join(", ")
        ),
        toml::Value::String(s) => format!("{s:?}"),
        other => other.to_string(),
    }
}

/// A settings table as `key = value` lines, in the order of `fields` (reports, `--explain`).
pub fn describe(table: &toml::Table, fields: &[FieldDoc]) -> String {
    let mut s = String::new();
    for f in fields {
        if let Some(v) = table.get(f.name) {
            let _ = writeln!(s, "{} = {}", f.name, display_value(v));
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    crate::filter_settings! {
        /// A test struct.
        pub struct Demo, flags "demo-" {
            /// A count.
            pub count: u32 = 3,
            /// A sigma
            /// on two lines.
            pub sigma: f32 = 0.1,
            pub list: [f32; 2] = [1.0, 2.0],
            pub switch: Auto<bool> = Auto::Auto,
            pub name: String = "rows".into(),
        }
    }

    #[test]
    fn defaults_tables_and_layers() {
        let d = Demo::default();
        let t = to_table(&d);
        assert_eq!(from_table::<Demo>(&t).unwrap(), d);
        // A partial table keeps the other defaults; an unknown key is an error naming it.
        let mut partial = toml::Table::new();
        partial.insert("count".into(), toml::Value::Integer(7));
        let got: Demo = from_table(&partial).unwrap();
        assert_eq!((got.count, got.sigma), (7, 0.1));
        partial.insert("cuont".into(), toml::Value::Integer(7));
        let e = from_table::<Demo>(&partial).unwrap_err().to_string();
        assert!(e.contains("cuont") && e.contains("`count`"), "{e}");
        // Floats round-trip exactly through TOML text.
        let text = toml::to_string(&t).unwrap();
        let back: Demo = from_table(&toml::from_str(&text).unwrap()).unwrap();
        assert_eq!(back, d);
    }

    #[test]
    fn flags_take_the_shape_of_the_default() {
        let t = to_table(&Demo::default());
        let v = |k: &str, raw: &str| parse_flag_value(raw, &t[k]);
        assert_eq!(v("count", "21"), toml::Value::Integer(21));
        assert_eq!(v("sigma", "0.5"), toml::Value::Float(0.5));
        assert_eq!(
            v("list", "1,2.5"),
            toml::Value::Array(vec![toml::Value::Integer(1), toml::Value::Float(2.5)])
        );
        assert_eq!(v("switch", "false"), toml::Value::Boolean(false));
        assert_eq!(v("switch", "auto"), toml::Value::String("auto".into()));
        assert_eq!(v("name", "naive"), toml::Value::String("naive".into()));
        let mut over = toml::Table::new();
        over.insert("list".into(), v("list", "1,2.5"));
        over.insert("switch".into(), v("switch", "true"));
        let mut base = t.clone();
        overlay(&mut base, &over);
        let d: Demo = from_table(&base).unwrap();
        assert_eq!((d.list, d.switch), ([1.0, 2.5], Auto::Set(true)));
        let mut bad = t.clone();
        bad.insert("switch".into(), toml::Value::String("maybe".into()));
        let e = from_table::<Demo>(&bad).unwrap_err().to_string();
        assert!(e.contains("auto"), "{e}");
    }

    #[test]
    fn docs_and_display() {
        let f = &Demo::fields()[1];
        assert_eq!(
            (f.name, f.help().as_str()),
            ("sigma", "A sigma on two lines.")
        );
        assert_eq!(f.flag(Demo::FLAG_PREFIX), "demo-sigma");
        assert!(Demo::fields()[3].is_switch());
        let text = describe(&to_table(&Demo::default()), Demo::fields());
        assert!(text.contains("sigma = 0.1\n"), "{text}");
        assert!(text.contains("list = [1.0, 2.0]\n"), "{text}");
        assert!(text.contains("switch = \"auto\"\n"), "{text}");
    }
}
