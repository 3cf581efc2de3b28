//! Case files: TOML in SI units. Parse → validate → build (docs/design.md, "Errors and input").
//!
//! - [`load_case`] reads a file into a `toml::Value` and applies `--set key.path=value` overrides;
//! - every typed section derives `Deserialize` with `deny_unknown_fields`, so unknown keys are rejected
//!   with their name ([`from_value`] turns serde's message into a [`ConfigError`]);
//! - every numeric key is checked against one declarative range table ([`ranges`]) with [`check`],
//!   whose error names key, value, allowed range and unit.

pub mod messages;
pub mod plausible;
pub mod ranges;

use crate::error::{ConfigError, Error};
use serde::de::DeserializeOwned;
use std::path::Path;

/// Reads a TOML case file and applies the command-line overrides (`key.path=value`).
pub fn load_case(path: &Path, overrides: &[String]) -> Result<toml::Value, Error> {
    let text = crate::io::read_input(path)?;
    let mut value = parse_case_str(&text, &path.display().to_string())?;
    // an empty file (or comments only) is no case: read as the default kind it would fail on a
    // missing [time] with nothing pointing at the real cause (issue 25)
    if value.as_table().is_some_and(|t| t.is_empty()) {
        return Err(ConfigError::invalid(format!(
            "{}: the file is empty (no keys, at most comments): a case needs at least its `kind` and sections, see docs/case-file.md or a bundled case in cases/",
            path.display()
        ))
        .into());
    }
    expand_includes(&mut value, path.parent().unwrap_or(Path::new(".")))?;
    for o in overrides {
        apply_override(&mut value, o)?;
    }
    apply_aliases(&mut value)?;
    Ok(value)
}

/// Parses case text (`name` appears in the error).
pub fn parse_case_str(text: &str, name: &str) -> Result<toml::Value, ConfigError> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    text.parse::<toml::Table>()
        .map(toml::Value::Table)
        .map_err(|e| ConfigError::invalid(format!("{name}{}: {}", position(text, e.span()), messages::syntax_message(text, e.span(), e.message()))))
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
///
/// A material file may also hold `[model]` (path factors, written by a calibration that fitted
/// them). Its keys become the case's `[model]` keys (a calibration file's `[path_factors]`) unless
/// the case sets that key itself: the case's own value wins, and `--set` after it. Two included
/// files that set one key to different values are refused: a run has one set of path factors.
/// Kinds without path factors (`heat`, `generate`, `explicit_sinter`) ignore an included `[model]`
/// (a heat case refused it as a compact-only section before: issue 26, class 13).
pub fn expand_includes(root: &mut toml::Value, base: &Path) -> Result<(), ConfigError> {
    let Some(list) = root.get_mut("materials").and_then(|m| m.as_array_mut()) else { return Ok(()) };
    // (include key, file, its [model])
    let mut models: Vec<(String, String, toml::Table)> = Vec::new();
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
        if let Some(m) = inc_root.get("model") {
            let t = m.as_table().ok_or_else(|| ConfigError::invalid(format!("{key} = \"{file}\": [model] is not a table")))?;
            // numbers only here; their names and ranges are checked with the case's [model] by the
            // kind that reads it (docs/decisions.md, "Included [model] tables")
            if let Some((k, v)) = t.iter().find(|(_, v)| !(v.is_float() || v.is_integer())) {
                return Err(ConfigError::invalid(format!("{key} = \"{file}\": [model] {k} = {v}: expected a number")));
            }
            models.push((key, file.to_string(), t.clone()));
        }
    }
    if models.is_empty() {
        return Ok(());
    }
    let target = if is_calibration(root) {
        "path_factors"
    } else if matches!(kind_name(root), "compact" | "pair") {
        "model"
    } else {
        return Ok(());
    };
    let Some(rt) = root.as_table_mut() else { return Ok(()) };
    let own = rt.entry(target.to_string()).or_insert_with(|| toml::Value::Table(toml::Table::new()));
    let own = own.as_table_mut().ok_or_else(|| ConfigError::invalid(format!("{target}: expected a table")))?;
    let explicit: Vec<String> = own.keys().cloned().collect();
    let number = |v: &toml::Value| v.as_float().or_else(|| v.as_integer().map(|i| i as f64));
    // key → (value, the include that set it)
    let mut set: Vec<(String, toml::Value, String)> = Vec::new();
    for (key, file, t) in &models {
        for (k, v) in t {
            if explicit.contains(k) {
                continue;
            }
            match set.iter().find(|(k0, _, _)| k0 == k) {
                Some((_, v0, by)) if number(v0) != number(v) => {
                    return Err(ConfigError::inconsistent(
                        format!("{key} = \"{file}\""),
                        format!(
                            "its [model] sets {k} = {v}, but {by} sets {k} = {v0}: a run has one set of path factors; set {target}.{k} in this file to choose"
                        ),
                    ));
                }
                Some(_) => {}
                None => set.push((k.clone(), v.clone(), format!("{key} = \"{file}\""))),
            }
        }
    }
    for (k, v, _) in set {
        own.insert(k, v);
    }
    Ok(())
}

/// Keys that mean one concept under another name in some kinds (docs/case-file.md, "One name per
/// concept"): (kind, common key, the kind's own key). A pair case's end time is `pair.end_time`;
/// `time.end`, the end time of heat and compact cases, names it too.
pub const ALIASES: &[(&str, &str, &str)] = &[("pair", "time.end", "pair.end_time")];

fn kind_name(root: &toml::Value) -> &str {
    root.get("kind").and_then(|k| k.as_str()).unwrap_or("heat")
}

/// The key of `path` in a case of `root`'s kind: the kind's own name for an [`ALIASES`] key.
pub fn alias_of<'a>(root: &toml::Value, path: &'a str) -> &'a str {
    let kind = kind_name(root);
    ALIASES.iter().find(|(k, common, _)| *k == kind && *common == path).map(|(_, _, own)| *own).unwrap_or(path)
}

/// Moves the [`ALIASES`] keys written in a case file under their common name to the kind's own
/// key (`[time] end = 60` of a pair case → `pair.end_time = 60`); both given is an error naming
/// both keys.
pub fn apply_aliases(root: &mut toml::Value) -> Result<(), ConfigError> {
    let kind = kind_name(root).to_string();
    for (k, common, own) in ALIASES.iter().filter(|a| a.0 == kind) {
        let (csec, ckey) = common.split_once('.').unwrap();
        let (osec, okey) = own.split_once('.').unwrap();
        let Some(t) = root.as_table_mut() else { return Ok(()) };
        let Some(value) = t.get_mut(csec).and_then(|s| s.as_table_mut()).and_then(|s| s.remove(ckey)) else { continue };
        if t.get(csec).and_then(|s| s.as_table()).is_some_and(|s| s.is_empty()) {
            t.remove(csec);
        } else if let Some(rest) = t.get(csec).and_then(|s| s.as_table()) {
            let extra: Vec<&String> = rest.keys().collect();
            return Err(ConfigError::inconsistent(
                format!("{csec}.{}", extra[0]),
                format!("unknown key: a {k} case takes only `{common}` in [{csec}] (the same as `{own}`)"),
            ));
        }
        let sec = t.entry(osec.to_string()).or_insert_with(|| toml::Value::Table(toml::Table::new()));
        let Some(sec) = sec.as_table_mut() else { continue };
        if sec.contains_key(okey) {
            return Err(ConfigError::inconsistent(*common, format!("and `{own}` name the same end time of a {k} case; give one of them")));
        }
        sec.insert(okey.to_string(), value);
    }
    Ok(())
}

/// Applies one `key.path=value` override. The value is parsed as TOML (number, bool, string,
/// array); a bare word that is not valid TOML is taken as a string. Array elements are addressed
/// by index (`profiles.0.hold_time=60`).
pub fn apply_override(root: &mut toml::Value, assignment: &str) -> Result<(), ConfigError> {
    let (path, raw) = assignment.split_once('=').ok_or_else(|| ConfigError::invalid(format!("--set {assignment}: expected key.path=value")))?;
    let path = alias_of(root, path.trim());
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

/// Whether a parsed TOML file is a calibration file rather than a case: `kind = "calibration"`,
/// or no `kind` and the calibration keys `data` and `parameters` (no case kind has either).
pub fn is_calibration(value: &toml::Value) -> bool {
    match value.get("kind") {
        Some(k) => k.as_str() == Some("calibration"),
        None => value.get("data").is_some() && value.get("parameters").is_some(),
    }
}

/// Deserialises a typed section (`section`: its dotted path in the case, "" for the whole case),
/// turning serde's message (unknown key, wrong type, missing key) into a [`ConfigError`] that
/// names the full key in a user's terms ([`messages::from_serde`]).
pub fn from_value<T: DeserializeOwned>(value: toml::Value, section: &str) -> Result<T, ConfigError> {
    T::deserialize(value).map_err(|e| messages::from_serde(&e.to_string(), section))
}

/// Checks `value` of a shared key against [`ranges::TABLE`] (see [`ranges::lookup`]); modules
/// with keys of their own use [`ranges::check_in`] with their table.
pub fn check(key: &str, value: f64) -> Result<f64, ConfigError> {
    ranges::check_in(&[], key, value)
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
        assert!(e.contains("case.toml:3:1") && e.contains("duplicate key `b` at the top level (first defined at line 2)"), "{e}");
        let e = super::parse_case_str("a = 1\n[x\n", "c.toml").unwrap_err().to_string();
        assert!(e.contains("c.toml:2:"), "{e}");
    }
}
