//! Configuration errors a user can act on (issue 14 item 7): serde's and toml's messages put in a
//! user's terms in one place.
//!
//! - unknown keys name the full key and the nearest valid key ("did you mean `time.dt`?", by
//!   Damerau–Levenshtein similarity, [`strsim`]), then the keys allowed there;
//! - type errors say "a number", "a whole number", "text", "a list", "true or false", "a table"
//!   instead of `f64`, `u32`, `a string`, `a sequence`, `a boolean`, `struct …`;
//! - [`locate`] adds `FILE:LINE:COLUMN` of the key an error names (or of the nearest table that
//!   exists, for a missing key), or says that the value came from `--set`;
//! - duplicate keys name the key, its table and the line of the first definition.

use crate::error::{ConfigError, Error};
use std::path::Path;

/// The key and message of a serde/toml deserialisation message, in a user's terms. `section` is
/// the dotted path of the deserialised value inside the case ("" for the whole case).
pub fn from_serde(raw: &str, section: &str) -> ConfigError {
    let raw = raw.trim().replace('\n', " ");
    // toml appends " in `path`" (the path of the value that failed, inside the deserialised value)
    let (body, inner) = match raw.rfind(" in `") {
        Some(i) if raw.ends_with('`') => (raw[..i].to_string(), raw[i + 5..raw.len() - 1].to_string()),
        _ => (raw.clone(), String::new()),
    };
    let join = |a: &str, b: &str| match (a.is_empty(), b.is_empty()) {
        (true, _) => b.to_string(),
        (_, true) => a.to_string(),
        _ => format!("{a}.{b}"),
    };
    let at = normalise_key(&join(section, &inner));
    if let Some(rest) = body.strip_prefix("unknown field `") {
        let (name, expected) = split_name(rest);
        let key = join(&at, &name);
        let allowed = backticked(&expected);
        let mut msg = "unknown key".to_string();
        if let Some(best) = nearest(&name, &allowed) {
            msg.push_str(&format!("; did you mean `{}`?", join(&at, best)));
        }
        if allowed.is_empty() {
            msg.push_str(" (this table takes no keys)");
        } else {
            let place = if at.is_empty() { "at the top level".to_string() } else { format!("in [{at}]") };
            msg.push_str(&format!(" (keys allowed {place}: {})", allowed.join(", ")));
        }
        return ConfigError::inconsistent(key, msg);
    }
    if let Some(rest) = body.strip_prefix("unknown variant `") {
        let (name, expected) = split_name(rest);
        let allowed = backticked(&expected);
        let mut msg = format!("\"{name}\" is not a known value");
        if let Some(best) = nearest(&name, &allowed) {
            msg.push_str(&format!("; did you mean \"{best}\"?"));
        }
        if !allowed.is_empty() {
            msg.push_str(&format!(" (allowed: {})", allowed.iter().map(|a| format!("\"{a}\"")).collect::<Vec<_>>().join(", ")));
        }
        return ConfigError::inconsistent(at, msg);
    }
    if let Some(rest) = body.strip_prefix("missing field `") {
        let name = rest.split('`').next().unwrap_or_default();
        let place = if at.is_empty() { "at the top level".to_string() } else { format!("in [{at}]") };
        return ConfigError::inconsistent(join(&at, name), format!("missing: this key is required {place}"));
    }
    for (prefix, invalid_value) in [("invalid type: ", false), ("invalid value: ", true)] {
        if let Some(rest) = body.strip_prefix(prefix)
            && let Some((got, expected)) = rest.rsplit_once(", expected ")
        {
            let want = expected_in_user_terms(expected);
            let got = got_in_user_terms(got);
            let msg = if invalid_value { format!("{got} is not allowed, expected {want}") } else { format!("expected {want}, got {got}") };
            return if at.is_empty() { ConfigError::invalid(msg) } else { ConfigError::inconsistent(at, msg) };
        }
    }
    let msg = if at.is_empty() { body } else { format!("{at}: {body}") };
    ConfigError::invalid(msg)
}

/// `name`, then what follows the closing backtick (", expected one of `a`, `b`").
fn split_name(rest: &str) -> (String, String) {
    match rest.split_once('`') {
        Some((name, tail)) => (name.to_string(), tail.to_string()),
        None => (rest.to_string(), String::new()),
    }
}

/// The backticked words of serde's "expected one of `a`, `b`".
fn backticked(s: &str) -> Vec<String> {
    s.split('`').skip(1).step_by(2).map(String::from).collect()
}

/// The allowed name nearest to `name`, when it is near enough to be a likely typo.
pub fn nearest<'a>(name: &str, allowed: &'a [String]) -> Option<&'a str> {
    let lower = name.to_lowercase();
    allowed
        .iter()
        .map(|a| (a, strsim::normalized_damerau_levenshtein(&lower, &a.to_lowercase()).max(strsim::jaro_winkler(&lower, &a.to_lowercase()) - 0.25)))
        .filter(|(_, s)| *s >= 0.5)
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(a, _)| a.as_str())
}

/// serde's expected type (`f64`, `u32`, `a string`, `a sequence`, `struct X`, …) in a user's terms.
fn expected_in_user_terms(e: &str) -> String {
    let e = e.trim();
    match e {
        "f64" | "f32" | "a number" => "a number".into(),
        "u8" | "u16" | "u32" | "u64" | "usize" => "a whole number >= 0".into(),
        "i8" | "i16" | "i32" | "i64" | "isize" => "a whole number".into(),
        "a string" | "a borrowed string" | "string" | "a character" | "char" => "text (in quotes)".into(),
        "a sequence" | "sequence" | "an array" => "a list [..]".into(),
        "a boolean" | "bool" => "true or false".into(),
        "a map" | "map" => "a table".into(),
        _ if e.starts_with("struct ") || e.starts_with("a table") => "a table".into(),
        _ if e.starts_with("a sequence of length") || e.starts_with("an array of length") => e.replace("a sequence", "a list").replace("an array", "a list"),
        _ if e.starts_with("enum ") || e.starts_with("variant identifier") => "one of the names listed for this key (docs/case-file.md)".into(),
        _ => e.to_string(),
    }
}

/// A number as serde prints it (fixed notation, up to ~330 digits for 5e-324 or 1.8e308) in
/// scientific notation when it is tiny or huge (|x| < 1e-4 or ≥ 1e16), else unchanged.
pub fn readable(s: &str) -> String {
    match s.parse::<f64>() {
        Ok(x) if x.is_finite() && x != 0.0 && (x.abs() < 1e-4 || x.abs() >= 1e16) => format!("{x:e}"),
        _ => s.to_string(),
    }
}

/// serde's `Unexpected` (`string "ten"`, `integer `3``, `floating point `8.5``, `boolean `true``,
/// `sequence`, `map`) in a user's terms.
fn got_in_user_terms(g: &str) -> String {
    let g = g.trim();
    let ticked = |s: &str| s.trim().trim_matches('`').to_string();
    if let Some(s) = g.strip_prefix("string ") {
        format!("the text {s}")
    } else if let Some(s) = g.strip_prefix("integer ") {
        format!("the whole number {}", ticked(s))
    } else if let Some(s) = g.strip_prefix("floating point ") {
        format!("the number {}", readable(&ticked(s)))
    } else if let Some(s) = g.strip_prefix("boolean ") {
        ticked(s)
    } else {
        match g {
            "sequence" => "a list [..]".into(),
            "map" => "a table".into(),
            other => other.to_string(),
        }
    }
}

/// `materials[0].density` → `materials.0.density` (the form of `--set` and of [`locate`]).
pub fn normalise_key(k: &str) -> String {
    k.replace("][", ".").replace('[', ".").replace(']', "").trim_matches('.').replace("..", ".")
}

/// The key a configuration error names, if any.
fn key_of(e: &ConfigError) -> Option<&str> {
    match e {
        ConfigError::OutOfRange { key, .. } | ConfigError::Inconsistent { key, .. } => Some(key),
        ConfigError::Invalid(_) => None,
    }
}

/// Adds where an error's key is: `FILE:LINE:COLUMN` in the case file `path` (the key itself, or
/// for a missing key the nearest enclosing table that exists), or "(set by --set …)" when one of
/// `overrides` set it. Errors without a key, and keys found nowhere, are returned unchanged.
pub fn locate(e: Error, path: &Path, overrides: &[String]) -> Error {
    let Error::Config(ce) = &e else { return e };
    let Some(key) = key_of(ce) else { return e };
    let key = normalise_key(key);
    let key = key.split(' ').next().unwrap_or_default().to_string();
    // the last override of the key wins (they are applied in order), and an override sets every
    // key under it; an element named by its index in --set may be named by its `name` in the error
    let case = if overrides.is_empty() { None } else { super::load_case(path, overrides).ok() };
    if let Some(o) = overrides.iter().rev().find(|o| o.split_once('=').is_some_and(|(k, _)| sets_key(&normalise_key(k.trim()), &key, case.as_ref()))) {
        return ConfigError::invalid(format!("{ce} (set by --set {o})")).into();
    }
    let Ok(text) = crate::io::read_input(path) else { return e };
    match key_position(&text, &key) {
        Some((line, col)) => ConfigError::invalid(format!("{}:{line}:{col}: {ce}", path.display())).into(),
        None => e,
    }
}

/// Whether the override of the dotted key `set` sets the dotted key `key` of an error: the same
/// key, or a key under it (`--set materials.0={…}` sets `materials.0.density`). A segment that is
/// an index in `set` matches the element's `name` in `key` (`materials.0.density` sets
/// `materials.copper.density`, the form of the material checks), looked up in `case` (the case
/// with the overrides applied).
fn sets_key(set: &str, key: &str, case: Option<&toml::Value>) -> bool {
    let (s, k): (Vec<&str>, Vec<&str>) = (set.split('.').collect(), key.split('.').collect());
    if s.len() > k.len() {
        return false;
    }
    fn named<'v>(n: Option<&'v toml::Value>, index: &str, name: &str) -> Option<&'v toml::Value> {
        let e = n?.as_array()?.get(index.parse::<usize>().ok()?)?;
        (e.get("name")?.as_str()? == name).then_some(e)
    }
    let mut node = case;
    for (a, b) in s.iter().zip(&k) {
        node = if a == b {
            node.and_then(|n| match n {
                toml::Value::Table(t) => t.get(*a),
                toml::Value::Array(v) => a.parse::<usize>().ok().and_then(|i| v.get(i)),
                _ => None,
            })
        } else if let Some(e) = named(node, a, b) {
            Some(e)
        } else {
            return false;
        };
    }
    true
}

/// 1-based line and column of the key `dotted` in the TOML `text`: of the key itself when
/// present, else of the deepest enclosing table or element that exists. An array element is named
/// by its index (`materials.1.density`), by its `name` (`materials.steel.phases.fcc.q_gb`, the
/// keys of the material checks), or not at all (`materials.phases.q_gbb`, serde's path of an
/// unknown key): then the element holding the rest of the path is found.
pub fn key_position(text: &str, dotted: &str) -> Option<(usize, usize)> {
    use toml::de::DeTable;
    let root = DeTable::parse(text).ok()?;
    let segs: Vec<&str> = dotted.split('.').filter(|s| !s.is_empty()).collect();
    let (_, span) = deepest_table(root.get_ref(), &segs);
    let p = super::position(text, Some(span?));
    let mut it = p.trim_start_matches(':').split(':').map(|x| x.parse::<usize>().ok());
    Some((it.next()??, it.next()??))
}

type Span = std::ops::Range<usize>;

/// (segments matched, span of the deepest match) of `segs` under table `t`.
fn deepest_table(t: &toml::de::DeTable, segs: &[&str]) -> (usize, Option<Span>) {
    let Some(seg) = segs.first() else { return (0, None) };
    let Some((k, v)) = t.iter().find(|(k, _)| k.get_ref().as_ref() == *seg) else { return (0, None) };
    let (n, span) = deepest_value(v.get_ref(), &segs[1..]);
    (n + 1, span.or(Some(k.span())))
}

/// (segments matched, span of the deepest match) of `segs` under value `v`.
fn deepest_value(v: &toml::de::DeValue, segs: &[&str]) -> (usize, Option<Span>) {
    use toml::de::DeValue;
    match v {
        DeValue::Table(t) => deepest_table(t, segs),
        DeValue::Array(a) => {
            let Some(seg) = segs.first() else { return (0, None) };
            let named = |e: &toml::de::DeValue| match e {
                DeValue::Table(t) => t.iter().any(|(k, v)| k.get_ref().as_ref() == "name" && matches!(v.get_ref(), DeValue::String(s) if s.as_ref() == *seg)),
                _ => false,
            };
            let by_index = seg.parse::<usize>().ok().and_then(|i| a.get(i));
            if let Some(e) = by_index.or_else(|| a.iter().find(|e| named(e.get_ref()))) {
                let (n, span) = deepest_value(e.get_ref(), &segs[1..]);
                return (n + 1, span.or(Some(e.span())));
            }
            // no index: the element that holds most of the path
            a.iter().map(|e| deepest_value(e.get_ref(), segs)).filter(|(n, _)| *n > 0).max_by_key(|(n, _)| *n).unwrap_or((0, None))
        }
        _ => (0, None),
    }
}

/// The message of a TOML syntax error at `span` of `text`, with the key named for a duplicate key.
pub fn syntax_message(text: &str, span: Option<std::ops::Range<usize>>, message: &str) -> String {
    let message = message.trim().trim_end_matches('.');
    let Some(span) = span.filter(|_| message.starts_with("duplicate key")) else { return message.to_string() };
    let (s, e) = (text.floor_char_boundary(span.start.min(text.len())), text.floor_char_boundary(span.end.min(text.len())));
    let key = text[s..e].trim().trim_matches(|c| c == '"' || c == '\'').to_string();
    if key.is_empty() {
        return message.to_string();
    }
    let line_no = text[..s].matches('\n').count() + 1;
    let lines: Vec<&str> = text.lines().collect();
    let this = lines.get(line_no - 1).copied().unwrap_or_default().trim_start();
    let header = |l: &str| {
        let l = l.trim();
        (l.starts_with('[')).then(|| l.trim_start_matches('[').split(']').next().unwrap_or_default().trim().to_string())
    };
    let key_of_line = |l: &str| l.split('=').next().map(|k| k.trim().trim_matches(|c| c == '"' || c == '\'').to_string());
    if let Some(h) = header(this) {
        // a table defined twice
        let first = lines[..line_no - 1].iter().position(|l| header(l).as_deref() == Some(h.as_str()));
        return format!("duplicate table [{h}]{}; merge the two into one", first.map(|i| format!(" (first defined at line {})", i + 1)).unwrap_or_default());
    }
    // a key defined twice in one table: the table is the nearest header above
    let mut table = String::new();
    let mut first = None;
    for (i, l) in lines[..line_no - 1].iter().enumerate().rev() {
        if let Some(h) = header(l) {
            table = h;
            break;
        }
        if first.is_none() && !l.trim_start().starts_with('#') && key_of_line(l).as_deref() == Some(key.as_str()) {
            first = Some(i + 1);
        }
    }
    let place = if table.is_empty() { "at the top level".to_string() } else { format!("in [{table}]") };
    let full = if table.is_empty() { key.clone() } else { format!("{table}.{key}") };
    format!(
        "duplicate key `{key}` {place}{}: `{full}` may be given once",
        first.map(|l| format!(" (first defined at line {l})")).unwrap_or_else(|| " (defined earlier on this line or above)".into())
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unknown_keys_get_the_nearest_valid_key() {
        let e = from_serde("unknown field `dtt`, expected one of `end`, `dt`, `scheme` in `time`", "").to_string();
        assert!(e.starts_with("time.dtt: unknown key; did you mean `time.dt`?"), "{e}");
        assert!(e.contains("keys allowed in [time]: end, dt, scheme"), "{e}");
        let e = from_serde("unknown field `outptu`, expected one of `time`, `output`, `particles`", "").to_string();
        assert!(e.contains("did you mean `output`?"), "{e}");
        let e = from_serde("unknown field `zzzzzz`, expected one of `time`, `output`", "").to_string();
        assert!(!e.contains("did you mean"), "{e}");
        let e = from_serde("unknown field `rtl`, expected `rtol`", "solver").to_string();
        assert!(e.contains("solver.rtl") && e.contains("did you mean `solver.rtol`?"), "{e}");
    }

    #[test]
    fn type_errors_are_in_user_terms() {
        let e = from_serde("invalid type: string \"ten\", expected f64 in `output.snapshots`", "").to_string();
        assert_eq!(e, "output.snapshots: expected a number, got the text \"ten\"");
        let e = from_serde("invalid type: floating point `8.5`, expected u32 in `particles.cells`", "").to_string();
        assert_eq!(e, "particles.cells: expected a whole number >= 0, got the number 8.5");
        // tiny and huge numbers in scientific notation, not ~330 digits (issue 26, class 13)
        assert_eq!(readable("-0.000000000000000000000000000000000000000000000000005"), "-5e-51");
        assert_eq!(readable(&format!("{}", -f64::MAX)), "-1.7976931348623157e308");
        assert_eq!(readable("0.5"), "0.5");
        let e = from_serde("invalid type: integer `3`, expected a string in `thermal.mode`", "").to_string();
        assert_eq!(e, "thermal.mode: expected text (in quotes), got the whole number 3");
        let e = from_serde("invalid type: integer `3`, expected a sequence in `walls.pressures`", "").to_string();
        assert_eq!(e, "walls.pressures: expected a list [..], got the whole number 3");
        let e = from_serde("invalid type: integer `1`, expected a boolean in `output.vtu`", "").to_string();
        assert_eq!(e, "output.vtu: expected true or false, got the whole number 1");
        let e = from_serde("invalid value: integer `-3`, expected u32 in `particles.cells`", "").to_string();
        assert_eq!(e, "particles.cells: the whole number -3 is not allowed, expected a whole number >= 0");
    }

    #[test]
    fn keys_are_located_in_the_text() {
        let text = "a = 1\n[time]\nend = 3\n\n[[m]]\nname = \"x\"\n[[m]]\nname = \"y\"\nrho = 3\n";
        assert_eq!(key_position(text, "time.end"), Some((3, 1)));
        assert_eq!(key_position(text, "time.dt"), Some((2, 2)), "a missing key: its table");
        assert_eq!(key_position(text, "m.1.rho"), Some((9, 1)));
        assert_eq!(key_position(text, "m[1].rho".replace('[', ".").replace(']', "").as_str()), Some((9, 1)));
        // an element by its name, or without index (serde's path of an unknown key)
        assert_eq!(key_position(text, "m.y.rho"), Some((9, 1)));
        assert_eq!(key_position(text, "m.rho"), Some((9, 1)));
        let text = "[[materials]]\nname = \"a\"\n[[materials.phases]]\nname = \"p\"\nq_gb = 1\n[[materials]]\nname = \"s\"\n[[materials.phases]]\nname = \"q\"\nd0 = 2\nq_gbb = 3\n";
        assert_eq!(key_position(text, "materials.phases.q_gbb"), Some((11, 1)));
        assert_eq!(key_position(text, "materials.s.phases.q.d0"), Some((10, 1)));
        assert_eq!(key_position(text, "materials.1.phases.0.d0"), Some((10, 1)));
        assert_eq!(key_position(text, "materials.a.phases.p.q_gb"), Some((5, 1)));
    }

    #[test]
    fn duplicate_keys_are_named_with_their_first_line() {
        let text = "a = 1\n[time]\nend = 3\ndt = 1\nend = 4\n";
        let m = syntax_message(text, Some(28..31), "duplicate key");
        assert_eq!(m, "duplicate key `end` in [time] (first defined at line 3): `time.end` may be given once");
        let text = "[t]\nx = 1\n[t]\ny = 2\n";
        let m = syntax_message(text, Some(11..12), "duplicate key");
        assert!(m.starts_with("duplicate table [t] (first defined at line 1)"), "{m}");
    }
}
