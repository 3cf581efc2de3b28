//! Helpers shared by the contact-law tests (`mod common;` in each test file).
#![allow(dead_code)]

use sinterdem::error::ConfigError;

/// Relative difference |a − b| / |b| [1].
pub fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs().max(f64::MIN_POSITIVE)
}

/// The key a configuration error names (or its message when it names none).
pub fn key_of(e: &ConfigError) -> String {
    match e {
        ConfigError::OutOfRange { key, .. } | ConfigError::Inconsistent { key, .. } => key.clone(),
        ConfigError::Invalid(m) => m.clone(),
    }
}

/// The `[section]` tables of the TOML code blocks of the document `doc`, in order.
pub fn doc_snippets(doc: &str, section: &str) -> Vec<toml::Value> {
    let text = std::fs::read_to_string(doc).unwrap();
    let mut out = Vec::new();
    let mut rest = text.as_str();
    while let Some(i) = rest.find("```toml\n") {
        let body = &rest[i + 8..];
        let j = body.find("```").unwrap();
        let t: toml::Table = body[..j].parse().unwrap();
        if let Some(v) = t.get(section) {
            out.push(v.clone());
        }
        rest = &body[j + 3..];
    }
    out
}
