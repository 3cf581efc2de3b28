//! Case files: TOML in SI units. Parse → validate → build (docs/design.md, "Errors and input").
//!
//! - [`load_case`] reads a file into a `toml::Value` and applies `--set key.path=value` overrides;
//! - every typed section derives `Deserialize` with `deny_unknown_fields`, so unknown keys are rejected
//!   with their name ([`from_value`] turns serde's message into a [`ConfigError`]);
//! - every numeric key is checked against one declarative range table ([`ranges`]) with [`check`],
//!   whose error names key, value, allowed range and unit.

pub mod case;
pub mod plausible;
pub mod ranges;

use crate::error::{ConfigError, Error};
use serde::de::DeserializeOwned;
use std::path::Path;

/// Reads a TOML case file and applies the command-line overrides (`key.path=value`).
pub fn load_case(path: &Path, overrides: &[String]) -> Result<toml::Value, Error> {
    let text = crate::io::read_input(path)?;
    let mut value = parse_case_str(&text, &path.display().to_string())?;
    expand_includes(&mut value, path.parent().unwrap_or(Path::new(".")))?;
    for o in overrides {
        apply_override(&mut value, o)?;
    }
    Ok(value)
}

/// Parses case text (`name` appears in the error).
pub fn parse_case_str(text: &str, name: &str) -> Result<toml::Value, ConfigError> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    text.parse::<toml::Table>().map(toml::Value::Table).map_err(|e| ConfigError::invalid(format!("{name}{}: {}", position(text, e.span()), e.message())))
}

/// `:LINE:COLUMN` (1-based) of the start of `span` in `text`, or "" without a span.
pub fn position(text: &str, span: Option<std::ops::Range<usize>>) -> String {
    let Some(span) = span else { return String::new() };
    let at = span.start.min(text.len());
    let before = &text[..text.floor_char_boundary(at)];
    let line = before.matches('\n').count() + 1;
    let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    format!(":{line}:{col}")
}

/// Expands `include = "file.toml"` in `[[materials]]` entries (docs/case-file.md, "Materials from
/// a file"): the entry starts from the material of the same name in the file's `[[materials]]`
/// (or its only material), and the entry's own keys win. `base` is the folder relative paths
/// start from (the case file's). Applies to every kind; a calibration's `material.toml` is such
/// a file.
pub fn expand_includes(root: &mut toml::Value, base: &Path) -> Result<(), ConfigError> {
    let Some(list) = root.get_mut("materials").and_then(|m| m.as_array_mut()) else { return Ok(()) };
    for (i, entry) in list.iter_mut().enumerate() {
        let Some(table) = entry.as_table_mut() else { continue };
        let Some(inc) = table.remove("include") else { continue };
        let key = format!("materials.{i}.include");
        let file = inc.as_str().ok_or_else(|| ConfigError::invalid(format!("{key} = {inc}: expected a file name (string)")))?;
        let path = base.join(file);
        let text = crate::io::read_input(&path).map_err(|e| ConfigError::invalid(format!("{key} = \"{file}\": cannot read {e}")))?;
        let inc_root: toml::Table = text.parse().map_err(|e: toml::de::Error| ConfigError::invalid(format!("{key}: {}: {}", path.display(), e.message())))?;
        let mats: Vec<toml::Table> =
            inc_root.get("materials").and_then(|m| m.as_array()).map(|a| a.iter().filter_map(|v| v.as_table().cloned()).collect()).unwrap_or_default();
        let name = table.get("name").and_then(|n| n.as_str()).map(String::from);
        let found = match &name {
            Some(n) => mats.iter().find(|m| m.get("name").and_then(|x| x.as_str()) == Some(n.as_str())).or(if mats.len() == 1 { mats.first() } else { None }),
            None if mats.len() == 1 => mats.first(),
            None => None,
        };
        let names: Vec<&str> = mats.iter().filter_map(|m| m.get("name").and_then(|x| x.as_str())).collect();
        let mut merged = found.cloned().ok_or_else(|| {
            ConfigError::invalid(format!(
                "{key} = \"{file}\": no material{} in {} (it has: {})",
                name.as_ref().map(|n| format!(" named \"{n}\"")).unwrap_or_default(),
                path.display(),
                names.join(", ")
            ))
        })?;
        if merged.contains_key("include") {
            return Err(ConfigError::invalid(format!("{key}: {} includes another file; one level of include only", path.display())));
        }
        for (k, v) in table.iter() {
            merged.insert(k.clone(), v.clone());
        }
        *table = merged;
    }
    Ok(())
}

/// Applies one `key.path=value` override. The value is parsed as TOML (number, bool, string,
/// array); a bare word that is not valid TOML is taken as a string. Array elements are addressed
/// by index (`profiles.0.hold_time=60`).
pub fn apply_override(root: &mut toml::Value, assignment: &str) -> Result<(), ConfigError> {
    let (path, raw) = assignment.split_once('=').ok_or_else(|| ConfigError::invalid(format!("--set {assignment}: expected key.path=value")))?;
    let path = path.trim();
    let raw = raw.trim();
    let new: toml::Value = match format!("v = {raw}").parse::<toml::Table>() {
        Ok(mut t) => t.remove("v").unwrap(),
        Err(_) => toml::Value::String(raw.to_string()),
    };
    let keys: Vec<&str> = path.split('.').collect();
    if keys.iter().any(|k| k.is_empty()) {
        return Err(ConfigError::invalid(format!("--set {assignment}: empty key in path")));
    }
    let mut cur = root;
    for (i, k) in keys.iter().enumerate() {
        let last = i + 1 == keys.len();
        cur = match cur {
            toml::Value::Table(t) => {
                if last {
                    t.insert(k.to_string(), new);
                    return Ok(());
                }
                t.entry(k.to_string()).or_insert_with(|| toml::Value::Table(toml::Table::new()))
            }
            toml::Value::Array(a) => {
                let idx: usize = k.parse().map_err(|_| ConfigError::invalid(format!("--set {assignment}: \"{k}\" must be an array index")))?;
                let len = a.len();
                let slot = a.get_mut(idx).ok_or_else(|| ConfigError::invalid(format!("--set {assignment}: index {idx} out of bounds (length {len})")))?;
                if last {
                    *slot = new;
                    return Ok(());
                }
                slot
            }
            _ => {
                return Err(ConfigError::invalid(format!("--set {assignment}: \"{}\" is not a table", keys[..i].join("."))));
            }
        };
    }
    Ok(())
}

/// Deserialises a typed section, turning serde's message (unknown field, wrong type) into a
/// [`ConfigError`] that names the key.
pub fn from_value<T: DeserializeOwned>(value: toml::Value, section: &str) -> Result<T, ConfigError> {
    T::deserialize(value).map_err(|e| {
        let msg = e.to_string();
        let msg = msg.trim().replace('\n', " ");
        if section.is_empty() { ConfigError::invalid(msg) } else { ConfigError::invalid(format!("[{section}] {msg}")) }
    })
}

/// Checks `value` of `key` against the range table entry for `key` (see [`ranges::lookup`]).
pub fn check(key: &str, value: f64) -> Result<f64, ConfigError> {
    let r = ranges::lookup(key).ok_or_else(|| ConfigError::invalid(format!("internal: key {key} has no entry in the range table")))?;
    r.check(key, value)
}

/// Checks an optional value (None passes).
pub fn check_opt(key: &str, value: Option<f64>) -> Result<Option<f64>, ConfigError> {
    value.map(|v| check(key, v)).transpose()
}

#[cfg(test)]
mod position_tests {
    #[test]
    fn syntax_errors_name_line_and_column() {
        let e = super::parse_case_str("a = 1\nb = 2\nb = 3\n", "case.toml").unwrap_err().to_string();
        assert!(e.contains("case.toml:3:1") && e.contains("duplicate key"), "{e}");
        let e = super::parse_case_str("a = 1\n[x\n", "c.toml").unwrap_err().to_string();
        assert!(e.contains("c.toml:2:"), "{e}");
    }
}
