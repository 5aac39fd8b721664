//! Loading description files (instrument, prior, scene) with errors that name
//! the file, the line and the field, and refuse impossible values.
//!
//! Parsing problems (syntax, a missing or unknown field, a wrong type) come
//! from the TOML deserialiser with their span. Impossible values (a negative
//! distance, an angle past 90 deg) are caught by [`Validate`] after parsing,
//! which names the field by path (`leds[2].distance_cm`); the loader then finds
//! that path's line in the source, so both kinds of error read the same way.
use serde::de::DeserializeOwned;
use std::fmt;
use std::path::Path;
use toml::de::{DeTable, DeValue};

/// An impossible value, found after parsing.
#[derive(Debug, Clone, PartialEq)]
pub struct FieldError {
    /// Path of the field, e.g. `leds[2].distance_cm`.
    pub path: String,
    /// What is wrong and what is allowed.
    pub message: String,
}

impl FieldError {
    /// A new error at `path`.
    pub fn new(path: impl Into<String>, message: impl Into<String>) -> Self {
        Self { path: path.into(), message: message.into() }
    }
    /// Prefixes the path with a parent (`parent.path` or `parent[i].path`).
    pub fn within(mut self, parent: &str) -> Self {
        self.path = if self.path.is_empty() {
            parent.to_string()
        } else if self.path.starts_with('[') {
            format!("{parent}{}", self.path)
        } else {
            format!("{parent}.{}", self.path)
        };
        self
    }
}

/// Semantic checks a description must pass after parsing.
pub trait Validate {
    /// Returns the first impossible value found.
    fn validate(&self) -> Result<(), FieldError>;
}

/// A description file that could not be used.
#[derive(Debug, Clone, PartialEq)]
pub struct ConfigError {
    /// File (or other origin) the text came from.
    pub origin: String,
    /// 1-based line and column, when known.
    pub line_col: Option<(usize, usize)>,
    /// Field path, when known.
    pub field: Option<String>,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.origin)?;
        if let Some((l, c)) = self.line_col {
            write!(f, ":{l}:{c}")?;
        }
        if let Some(field) = &self.field {
            write!(f, ": field `{field}`")?;
        }
        write!(f, ": {}", self.message)
    }
}

impl std::error::Error for ConfigError {}

/// Parses and validates `text`; `origin` names it in errors.
pub fn parse_toml<T: DeserializeOwned + Validate>(text: &str, origin: &str) -> Result<T, ConfigError> {
    let value: T = toml::from_str(text).map_err(|e| ConfigError {
        origin: origin.to_string(),
        line_col: e.span().map(|s| line_col(text, s.start)),
        field: None,
        message: e.message().trim().to_string(),
    })?;
    value.validate().map_err(|fe| ConfigError {
        origin: origin.to_string(),
        line_col: locate(text, &fe.path).map(|off| line_col(text, off)),
        field: Some(fe.path.clone()),
        message: fe.message,
    })?;
    Ok(value)
}

/// Reads, parses and validates a description file.
pub fn load_toml<T: DeserializeOwned + Validate>(path: &Path) -> Result<T, ConfigError> {
    let origin = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|e| ConfigError {
        origin: origin.clone(),
        line_col: None,
        field: None,
        message: format!("cannot read the file: {e}"),
    })?;
    parse_toml(&text, &origin)
}

fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, col)
}

/// Byte offset of the value at `path` (`a.b[2].c`) in `text`, or of the
/// deepest parent that exists.
fn locate(text: &str, path: &str) -> Option<usize> {
    let root = DeTable::parse(text).ok()?;
    let mut table: &DeTable = root.get_ref();
    let mut found = None;
    for seg in path.split('.') {
        let (key, idx) = match seg.find('[') {
            Some(b) => (&seg[..b], seg[b + 1..].trim_end_matches(']').parse::<usize>().ok()),
            None => (seg, None),
        };
        // A missing key (e.g. a missing field) leaves the deepest parent found.
        let Some((_, value)) = table.iter().find(|(k, _)| k.get_ref().as_ref() == key) else { break };
        found = Some(value.span().start);
        let mut v = value.get_ref();
        if let (Some(i), DeValue::Array(items)) = (idx, v) {
            let item = items.get(i)?;
            found = Some(item.span().start);
            v = item.get_ref();
        }
        match v {
            DeValue::Table(t) => table = t,
            _ => break,
        }
    }
    found
}

/// Checks that `value` is finite and within `[lo, hi]`.
pub fn check_range(path: &str, value: f64, lo: f64, hi: f64, unit: &str) -> Result<(), FieldError> {
    if value.is_finite() && value >= lo && value <= hi {
        Ok(())
    } else {
        Err(FieldError::new(path, format!("{value} is impossible; allowed {lo}..={hi} {unit}")))
    }
}

/// Checks that `value` is finite and strictly positive.
pub fn check_positive(path: &str, value: f64, unit: &str) -> Result<(), FieldError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(FieldError::new(path, format!("{value} is impossible; must be > 0 {unit}")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::Deserialize;

    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Doc {
        leds: Vec<Led>,
    }
    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Led {
        distance_cm: f64,
    }
    impl Validate for Doc {
        fn validate(&self) -> Result<(), FieldError> {
            for (i, l) in self.leds.iter().enumerate() {
                check_positive("distance_cm", l.distance_cm, "cm").map_err(|e| e.within(&format!("leds[{i}]")))?;
            }
            Ok(())
        }
    }

    #[test]
    fn impossible_value_names_file_line_and_field() {
        let text = "[[leds]]\ndistance_cm = 10.0\n\n[[leds]]\ndistance_cm = -3.0\n";
        let e = parse_toml::<Doc>(text, "inst.toml").unwrap_err();
        assert_eq!(e.field.as_deref(), Some("leds[1].distance_cm"));
        assert_eq!(e.line_col.map(|l| l.0), Some(5));
        let s = e.to_string();
        assert!(s.starts_with("inst.toml:5:") && s.contains("leds[1].distance_cm") && s.contains("-3"), "{s}");
    }

    #[test]
    fn syntax_unknown_and_missing_fields_name_the_line() {
        let e = parse_toml::<Doc>("[[leds]]\ndistance_cm = 1.0\nbogus = 2\n", "a.toml").unwrap_err();
        assert_eq!(e.line_col.map(|l| l.0), Some(3), "{e}");
        assert!(e.message.contains("bogus"), "{e}");
        let e = parse_toml::<Doc>("[[leds]]\n", "a.toml").unwrap_err();
        assert!(e.message.contains("distance_cm"), "{e}");
        assert!(e.line_col.is_some());
        let e = parse_toml::<Doc>("[[leds]\ndistance_cm = 1.0\n", "a.toml").unwrap_err();
        assert_eq!(e.line_col.map(|l| l.0), Some(1), "{e}");
    }
}
