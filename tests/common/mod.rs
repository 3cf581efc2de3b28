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

/// A fresh, empty directory `sinterdem-{prefix}-{name}-{pid}` under the system temp dir.
pub fn fresh_dir(prefix: &str, name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("sinterdem-{prefix}-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The data lines of the bundled green copper packing (`cases/data/green-copper.csv`, columns
/// x, y, z, r [m]) whose centre has x, y below `edge` and z below `height` [m], with the values.
pub fn green_copper_block(edge: f64, height: f64) -> Vec<(String, [f64; 4])> {
    let text = std::fs::read_to_string("cases/data/green-copper.csv").unwrap();
    text.lines()
        .filter(|l| !l.starts_with('#') && !l.starts_with('x'))
        .map(|line| {
            let v: Vec<f64> = line.split(',').map(|s| s.parse().unwrap()).collect();
            (line.to_string(), [v[0], v[1], v[2], v[3]])
        })
        .filter(|(_, v)| v[0] < edge && v[1] < edge && v[2] < height)
        .collect()
}

/// Writes `header` and the `lines` of a packing block to `dir/file`; returns the path.
pub fn write_block(dir: &std::path::Path, file: &str, header: &str, lines: impl IntoIterator<Item = String>) -> std::path::PathBuf {
    let mut out = format!("{header}\n");
    for l in lines {
        out.push_str(&l);
        out.push('\n');
    }
    let path = dir.join(file);
    std::fs::write(&path, out).unwrap();
    path
}
