//! The output manifest (issue 38, docs/outputs.md "Guarantees"): every command that writes an
//! output directory (`run`, `resume`, `study`, `calibrate`, `generate`, `rve`) keeps
//! `DIR/outputs.json`, the list of the files it wrote there. A file is entered (and the manifest
//! rewritten atomically) *before* the file is created, so a run killed at any point has recorded
//! every file it may have left. A rerun or `--force` removes exactly these files
//! ([`crate::io::outdir::clear`]); a file or folder sinterdem did not record is never removed.
//!
//! The writers ([`crate::io::write_atomic_bytes`], [`crate::io::Series`], the VTU, HDF5 and log
//! writers) call [`record`] with the path they are about to create; the entry goes to the manifest
//! of the innermost open output directory holding it (a study's `runs/NNNN` has its own, and the
//! study's lists `runs/NNNN` among its `dirs`). A directory is open from [`begin`] (its command
//! claimed it) until its output lock is released ([`end`]).

use crate::error::IoError;
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// File name of the manifest inside an output directory.
pub const MANIFEST: &str = "outputs.json";

/// The manifest's content: paths relative to its directory, `/`-separated.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Manifest {
    #[serde(default)]
    pub sinterdem: String,
    /// Files this directory's commands wrote (created or replaced).
    #[serde(default)]
    pub files: BTreeSet<String>,
    /// Subdirectories holding the outputs of a nested command, with their own manifest.
    #[serde(default)]
    pub dirs: BTreeSet<String>,
}

/// The open output directories of this process: (canonical directory, its manifest).
static OPEN: Mutex<Vec<(PathBuf, Manifest)>> = Mutex::new(Vec::new());

fn open_dirs() -> std::sync::MutexGuard<'static, Vec<(PathBuf, Manifest)>> {
    OPEN.lock().unwrap_or_else(|e| e.into_inner())
}

/// `dir` made absolute with symbolic links resolved (as given when it does not exist).
fn canonical(dir: &Path) -> PathBuf {
    std::fs::canonicalize(dir).or_else(|_| std::path::absolute(dir)).unwrap_or_else(|_| dir.to_path_buf())
}

/// `path` (a file that may not exist yet) with its folder made canonical.
fn canonical_file(path: &Path) -> PathBuf {
    match (path.parent(), path.file_name()) {
        (Some(p), Some(n)) if !p.as_os_str().is_empty() => canonical(p).join(n),
        (_, Some(n)) => canonical(Path::new(".")).join(n),
        _ => canonical(path),
    }
}

/// Whether `a` and `b` name the same directory.
pub fn same_dir(a: &Path, b: &Path) -> bool {
    canonical(a) == canonical(b)
}

fn relative(path: &Path, root: &Path) -> Option<String> {
    let rel = path.strip_prefix(root).ok()?;
    let parts: Vec<String> = rel.components().map(|c| c.as_os_str().to_string_lossy().into_owned()).collect();
    (!parts.is_empty()).then(|| parts.join("/"))
}

/// Writes the manifest of `root` atomically (a temporary file, then a rename).
fn store(root: &Path, m: &Manifest) -> Result<(), IoError> {
    let path = root.join(MANIFEST);
    let mut m = m.clone();
    m.sinterdem = env!("CARGO_PKG_VERSION").into();
    let text = serde_json::to_string_pretty(&m).map_err(|e| IoError::new(&path, e))? + "\n";
    let tmp = root.join(format!("{MANIFEST}.tmp{}", std::process::id()));
    if let Err(e) = std::fs::write(&tmp, text) {
        let _ = std::fs::remove_file(&tmp);
        return Err(IoError::new(&tmp, e));
    }
    std::fs::rename(&tmp, &path).map_err(|e| IoError::new(&path, e))
}

/// The manifest of `dir` (None: it has none; an unreadable manifest is an error: what it lists
/// cannot be told).
pub fn read(dir: &Path) -> Result<Option<Manifest>, IoError> {
    let path = dir.join(MANIFEST);
    match std::fs::read_to_string(&path) {
        Ok(t) => serde_json::from_str(&t).map(Some).map_err(|e| IoError::new(&path, format!("is not a sinterdem output manifest ({e})"))),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(IoError::new(&path, e)),
    }
}

/// Opens `dir` for a command that writes it: with `keep`, the files its manifest already lists
/// stay listed (`resume`, a study or calibration continued); else the manifest starts empty (the
/// earlier outputs were removed). The manifest is written at once, before any output.
pub fn begin(dir: &Path, keep: bool) -> Result<(), IoError> {
    let root = canonical(dir);
    let m = if keep { read(&root)?.unwrap_or_default() } else { Manifest::default() };
    store(&root, &m)?;
    let mut open = open_dirs();
    open.retain(|(r, _)| r != &root);
    // a nested output directory (a study's runs/NNNN) is listed in the enclosing one's manifest
    if let Some((proot, pm)) = open.iter_mut().filter(|(r, _)| root.starts_with(r)).max_by_key(|(r, _)| r.as_os_str().len())
        && let Some(rel) = relative(&root, proot)
        && pm.dirs.insert(rel)
    {
        store(proot, pm)?;
    }
    open.push((root, m));
    Ok(())
}

/// Closes `dir` (its lock is released): later writes there are no longer recorded.
pub fn end(dir: &Path) {
    let root = canonical(dir);
    open_dirs().retain(|(r, _)| r != &root);
}

/// Enters `path` in the manifest of the innermost open output directory holding it, before the
/// caller creates it. A path outside every open directory is not recorded (Ok).
pub fn record(path: &Path) -> Result<(), IoError> {
    let mut open = open_dirs();
    if open.is_empty() {
        return Ok(());
    }
    let full = canonical_file(path);
    let Some((root, m)) = open.iter_mut().filter(|(r, _)| full.starts_with(r) && &full != r).max_by_key(|(r, _)| r.as_os_str().len()) else {
        return Ok(());
    };
    let Some(rel) = relative(&full, root) else { return Ok(()) };
    if rel == MANIFEST || !m.files.insert(rel) {
        return Ok(());
    }
    store(root, m)
}

/// Whether `name` is `file` or a temporary file of an atomic write of it (`file.tmpNNN`).
fn is_file_or_its_temporary(name: &str, file: &str) -> bool {
    name == file || name.strip_prefix(file).and_then(|r| r.strip_prefix(".tmp")).is_some_and(|d| !d.is_empty() && d.bytes().all(|b| b.is_ascii_digit()))
}

/// What removing the recorded outputs of `dir` takes: files (existing ones, their leftover
/// temporary files, nested manifests' files, the manifests themselves) and the directories to try
/// to remove afterwards (only when empty), deepest first. Files in `protected` (the inputs of the
/// coming run) are left and listed in `kept_inputs`.
#[derive(Debug, Default)]
pub struct Removal {
    pub files: Vec<PathBuf>,
    pub dirs: Vec<PathBuf>,
    pub kept_inputs: Vec<PathBuf>,
}

/// The [`Removal`] of `dir`'s recorded outputs (None: `dir` has no manifest).
pub fn removal(dir: &Path, protected: &[PathBuf]) -> Result<Option<Removal>, IoError> {
    let Some(m) = read(dir)? else { return Ok(None) };
    let protected: Vec<PathBuf> = protected.iter().map(|p| canonical_file(p)).collect();
    let mut r = Removal::default();
    collect(dir, &m, &protected, &mut r, 4)?;
    r.dirs.sort_by_key(|d| std::cmp::Reverse(d.components().count()));
    r.dirs.dedup();
    Ok(Some(r))
}

fn collect(dir: &Path, m: &Manifest, protected: &[PathBuf], r: &mut Removal, depth: usize) -> Result<(), IoError> {
    let mut subdirs: BTreeSet<PathBuf> = BTreeSet::new();
    for f in &m.files {
        // a recorded path never leaves its directory
        if f.split('/').any(|c| c.is_empty() || c == "." || c == "..") {
            continue;
        }
        let path = dir.join(f);
        let folder = path.parent().unwrap_or(dir).to_path_buf();
        let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        if protected.contains(&canonical_file(&path)) {
            r.kept_inputs.push(path);
            continue;
        }
        if let Ok(es) = std::fs::read_dir(&folder) {
            for e in es.flatten() {
                let n = e.file_name().to_string_lossy().into_owned();
                if is_file_or_its_temporary(&n, &name) && e.file_type().is_ok_and(|t| !t.is_dir()) {
                    r.files.push(e.path());
                }
            }
        }
        if folder != dir {
            subdirs.insert(folder);
        }
    }
    for d in &m.dirs {
        if !d.split('/').any(|c| c.is_empty() || c == "." || c == "..") {
            subdirs.insert(dir.join(d));
        }
    }
    for sub in subdirs {
        // every folder between `dir` and `sub` may become empty
        let mut p = sub.clone();
        while p != dir && p.starts_with(dir) {
            r.dirs.push(p.clone());
            p = p.parent().unwrap_or(dir).to_path_buf();
        }
        if depth > 0
            && let Some(nested) = read(&sub)?
        {
            collect(&sub, &nested, protected, r, depth - 1)?;
        }
    }
    for e in std::fs::read_dir(dir).into_iter().flatten().flatten() {
        if is_file_or_its_temporary(&e.file_name().to_string_lossy(), MANIFEST) {
            r.files.push(e.path());
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recorded_files_go_to_the_innermost_open_directory_and_only_they_are_listed_for_removal() {
        let d = std::env::temp_dir().join(format!("sinterdem-manifest-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(d.join("runs/0000")).unwrap();
        begin(&d, false).unwrap();
        record(&d.join("plan.json")).unwrap();
        std::fs::write(d.join("plan.json"), "[]").unwrap();
        begin(&d.join("runs/0000"), false).unwrap();
        record(&d.join("runs/0000/summary.json")).unwrap();
        std::fs::write(d.join("runs/0000/summary.json"), "{}").unwrap();
        std::fs::write(d.join("runs/0000/summary.json.tmp123"), "{").unwrap();
        end(&d.join("runs/0000"));
        std::fs::write(d.join("runs/0000/mine.txt"), "user").unwrap();
        std::fs::write(d.join("notes.txt"), "user").unwrap();
        // written after the directory was closed: not recorded
        end(&d);
        record(&d.join("late.csv")).unwrap();
        let top = read(&d).unwrap().unwrap();
        assert_eq!(top.files.iter().collect::<Vec<_>>(), ["plan.json"]);
        assert_eq!(top.dirs.iter().collect::<Vec<_>>(), ["runs/0000"]);
        let r = removal(&d, &[]).unwrap().unwrap();
        let mut names: Vec<String> = r.files.iter().map(|p| p.strip_prefix(&d).unwrap().to_string_lossy().into_owned()).collect();
        names.sort();
        assert_eq!(names, ["outputs.json", "plan.json", "runs/0000/outputs.json", "runs/0000/summary.json", "runs/0000/summary.json.tmp123"]);
        assert_eq!(r.dirs, [d.join("runs/0000"), d.join("runs")]);
        let kept = removal(&d, &[d.join("plan.json")]).unwrap().unwrap();
        assert_eq!(kept.kept_inputs, [d.join("plan.json")]);
        let _ = std::fs::remove_dir_all(&d);
    }
}
