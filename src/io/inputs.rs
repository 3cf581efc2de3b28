//! The input files of a run, fingerprinted (docs/outputs.md "Guarantees"): a run writes
//! `DIR/inputs.json` before its first step, with the SHA-256 of every file its case names (a
//! `file = "…"` key anywhere in the case: today the packing of `[particles] source = "file"`),
//! and `resume` refuses to continue when one of them changed since — a checkpoint rebuilds the
//! run from its case text, so an edited packing would otherwise be used silently. The case text
//! itself (includes expanded) is frozen inside the checkpoint.

use crate::error::{ConfigError, Error, IoError};
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};

/// Name of the fingerprint file in an output directory.
pub const INPUTS_FILE: &str = "inputs.json";

/// One fingerprinted input: the case key that names it, its path and its SHA-256 (hex).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct InputFile {
    pub key: String,
    pub path: PathBuf,
    pub bytes: u64,
    pub sha256: String,
}

/// The files a case names: every string at a key `file` (dotted key path, path resolved against
/// `base`).
pub fn referenced_files(case: &toml::Value, base: &Path) -> Vec<(String, PathBuf)> {
    fn walk(v: &toml::Value, prefix: &str, base: &Path, out: &mut Vec<(String, PathBuf)>) {
        match v {
            toml::Value::Table(t) => {
                for (k, x) in t {
                    let key = if prefix.is_empty() { k.clone() } else { format!("{prefix}.{k}") };
                    match x {
                        toml::Value::String(s) if k == "file" => out.push((key, base.join(s))),
                        _ => walk(x, &key, base, out),
                    }
                }
            }
            toml::Value::Array(a) => {
                for (i, x) in a.iter().enumerate() {
                    walk(x, &format!("{prefix}.{i}"), base, out);
                }
            }
            _ => {}
        }
    }
    let mut out = Vec::new();
    walk(case, "", base, &mut out);
    out
}

/// SHA-256 of a file, hex.
pub(crate) fn digest(path: &Path) -> Result<(u64, String), IoError> {
    let bytes = std::fs::read(path).map_err(|e| IoError::new(path, e))?;
    let hash = Sha256::digest(&bytes);
    Ok((bytes.len() as u64, hash.iter().map(|b| format!("{b:02x}")).collect()))
}

/// Fingerprints the files `case` names and writes them to `dir/inputs.json` (atomically). Files
/// that do not exist are left out (the run itself reports them).
pub fn record(dir: &Path, case: &toml::Value, base: &Path) -> Result<Vec<InputFile>, IoError> {
    let mut files = Vec::new();
    for (key, path) in referenced_files(case, base) {
        if let Ok((bytes, sha256)) = digest(&path) {
            let path = path.canonicalize().unwrap_or(path);
            files.push(InputFile { key, path, bytes, sha256 });
        }
    }
    let text = serde_json::to_string_pretty(&files).map_err(|e| IoError::new(dir.join(INPUTS_FILE), e))?;
    crate::io::write_atomic(&dir.join(INPUTS_FILE), &(text + "\n"))?;
    Ok(files)
}

/// Checks before a resume that every input recorded in `dir/inputs.json` is unchanged. A
/// directory without the file (a run of an older sinterdem) passes with nothing checked (None);
/// otherwise the number of files checked.
pub fn verify(dir: &Path) -> Result<Option<usize>, Error> {
    let path = dir.join(INPUTS_FILE);
    let text = match std::fs::read_to_string(&path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(IoError::new(&path, e).into()),
    };
    let files: Vec<InputFile> = serde_json::from_str(&text).map_err(|e| IoError::new(&path, format!("not an inputs fingerprint: {e}")))?;
    for f in &files {
        let now = digest(&f.path).map_err(|e| {
            Error::from(ConfigError::inconsistent(
                f.key.clone(),
                format!("= {}: the input of this run cannot be read any more ({e}); a resume needs the same inputs", f.path.display()),
            ))
        })?;
        if now != (f.bytes, f.sha256.clone()) {
            return Err(ConfigError::inconsistent(
                f.key.clone(),
                format!(
                    "= {}: the file changed since the run started ({} bytes, SHA-256 {}…; now {} bytes, {}…): a resume must continue with the same inputs — restore the file, or start a new run",
                    f.path.display(),
                    f.bytes,
                    &f.sha256[..12],
                    now.0,
                    &now.1[..12]
                ),
            )
            .into());
        }
    }
    Ok(Some(files.len()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn file_keys_are_found_anywhere_and_a_changed_file_is_refused() {
        let d = std::env::temp_dir().join(format!("sinterdem-inputs-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        std::fs::write(d.join("p.csv"), "x,y,z,r\n0,0,0,1e-5\n").unwrap();
        let case: toml::Value = toml::Value::Table("[particles]\nsource = \"file\"\nfile = \"p.csv\"\n[[x]]\nfile = \"missing.csv\"\n".parse().unwrap());
        let refs = referenced_files(&case, &d);
        assert_eq!(refs.iter().map(|r| r.0.as_str()).collect::<Vec<_>>(), ["particles.file", "x.0.file"]);
        let rec = record(&d, &case, &d).unwrap();
        assert_eq!(rec.len(), 1, "a missing file is left out");
        assert_eq!(rec[0].sha256.len(), 64);
        assert_eq!(verify(&d).unwrap(), Some(1));
        std::fs::write(d.join("p.csv"), "x,y,z,r\n0,0,0,1.03e-5\n").unwrap();
        let e = verify(&d).unwrap_err().to_string();
        assert!(e.contains("particles.file") && e.contains("changed since the run started"), "{e}");
        std::fs::remove_file(d.join("p.csv")).unwrap();
        assert!(verify(&d).unwrap_err().to_string().contains("cannot be read any more"));
        std::fs::remove_file(d.join(INPUTS_FILE)).unwrap();
        assert_eq!(verify(&d).unwrap(), None, "an older run's directory has nothing to check");
        let _ = std::fs::remove_dir_all(&d);
    }
}
