//! Clean output directories (issue 25, docs/outputs.md "Guarantees", docs/decisions.md "Clean
//! output directories"): a command that writes `--out DIR` first looks whether `DIR` holds the
//! outputs of an earlier command. A `run` (every kind, `generate` and `rve` too) refuses such a
//! directory unless `--force` is given; with `--force` the earlier outputs are removed before the
//! first file is written, so that a directory never mixes two runs (ParaView groups
//! `particles_*.vtu` by name). `study` and `calibrate` continue their own kind of directory (a
//! killed study or calibration is finished by running it again, reusing its finished runs) and
//! refuse the others.
//! `resume` continues its own run and is not concerned.

use crate::error::IoError;
use crate::io::manifest::MANIFEST;
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};

/// The run marker: written by every run at its start, with the fingerprint of its case
/// ([`case_fingerprint`]), so that a rerun of the same case is told from another run.
pub const RUN_MARKER: &str = "run.json";

/// Files that show a run's results at the top of its directory (any kind). `log.txt` and
/// `inputs.json` alone do not: a run refused at its start (a bad key) writes them, and the next run
/// rewrites both, so fixing the case and running again needs no `--force`.
const RUN_MARKERS: &[&str] = &["summary.json", "checkpoint.json", "series.csv", "sinterdem.h5", "packing.csv", "dl_bar_end.csv"];
/// Files that only a study writes at the top of its directory.
const STUDY_MARKERS: &[&str] = &["plan.json", "study.csv", "study.json", "executions.log"];
/// Files that only a calibration writes at the top of its directory.
const CALIBRATION_MARKERS: &[&str] = &["calibration.json", "residuals.csv"];

/// What an output directory holds from an earlier command.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Held {
    /// Nothing a sinterdem command wrote (missing, empty, or only other files and the lock).
    Nothing,
    /// A run's outputs (any kind); the names that show it (at most a few).
    Run(Vec<String>),
    /// A study's outputs (`plan.json`, `study.csv`, …).
    Study(Vec<String>),
    /// A calibration's outputs (`calibration.json`, `residuals.csv`).
    Calibration(Vec<String>),
}

impl Held {
    /// A phrase for messages: "the outputs of a run (summary.json, log.txt, …)".
    pub fn describe(&self) -> String {
        let (what, names) = match self {
            Held::Nothing => return "nothing of an earlier command".into(),
            Held::Run(n) => ("a run", n),
            Held::Study(n) => ("a study", n),
            Held::Calibration(n) => ("a calibration", n),
        };
        format!("the outputs of {what} ({})", names.join(", "))
    }
}

/// Whether `name` is a snapshot file of a run: `particles_NNNNNN.vtu`, `contacts_NNNNNN.vtu` and
/// their `.pvd` indices (the file series ParaView groups by name).
pub fn is_snapshot_file(name: &str) -> bool {
    if matches!(name, "particles.pvd" | "contacts.pvd") {
        return true;
    }
    ["particles_", "contacts_"]
        .iter()
        .any(|p| name.strip_prefix(p).and_then(|r| r.strip_suffix(".vtu")).is_some_and(|d| !d.is_empty() && d.bytes().all(|b| b.is_ascii_digit())))
}

/// What `dir` holds from an earlier command (a study or calibration wins over the run files it
/// also holds: a study directory has no top-level `summary.json`, but a calibration's may have a
/// `log.txt`).
pub fn held(dir: &Path) -> Held {
    let Ok(entries) = std::fs::read_dir(dir) else { return Held::Nothing };
    let names: Vec<String> = entries.flatten().filter_map(|e| e.file_name().to_str().map(str::to_string)).collect();
    held_names(names)
}

/// [`held`] of a directory holding the entries `names`.
fn held_names(mut names: Vec<String>) -> Held {
    names.sort();
    let pick = |set: &[&str]| -> Vec<String> { names.iter().filter(|n| set.contains(&n.as_str())).cloned().collect() };
    let study = pick(STUDY_MARKERS);
    if !study.is_empty() {
        return Held::Study(study);
    }
    let calibration = pick(CALIBRATION_MARKERS);
    if !calibration.is_empty() {
        return Held::Calibration(calibration);
    }
    let mut run = pick(RUN_MARKERS);
    let snapshots = names.iter().filter(|n| is_snapshot_file(n)).count();
    if snapshots > 0 {
        run.push(format!("{snapshots} snapshot file{}", if snapshots == 1 { "" } else { "s" }));
    }
    if run.is_empty() { Held::Nothing } else { Held::Run(run) }
}

/// What `--force` removed: counts for the log line, and what was kept (every file and folder no
/// sinterdem command recorded as its output, and the inputs of the coming run).
#[derive(Debug, Default, Clone, PartialEq, Eq)]
pub struct Cleared {
    pub files: usize,
    pub dirs: usize,
    pub kept: Vec<String>,
}

impl Cleared {
    /// The log line of a forced clear.
    pub fn note(&self, held: &Held) -> String {
        let mut s = format!(
            "--force: removed {} ({} file{} and {} director{}, as listed in {MANIFEST}) before this run",
            held.describe(),
            self.files,
            if self.files == 1 { "" } else { "s" },
            self.dirs,
            if self.dirs == 1 { "y" } else { "ies" }
        );
        if !self.kept.is_empty() {
            s.push_str(&format!("; kept {} (not written by sinterdem, or read by this run)", self.kept.join(", ")));
        }
        s
    }
}

/// Removes the earlier outputs in `dir`: exactly the files its output manifest ([`MANIFEST`],
/// `crate::io::manifest`) lists (and those of the nested output directories it lists), then the
/// folders they leave empty. Every other file and folder stays, and so do the files of
/// `protected` (what the coming run reads). Refused, before anything is removed, when outputs
/// would remain that no manifest lists (a directory written by an older sinterdem, or files a
/// user put there under sinterdem's names): which of them sinterdem wrote cannot be told.
pub fn clear(dir: &Path, protected: &[PathBuf]) -> Result<Cleared, IoError> {
    let removal = crate::io::manifest::removal(dir, protected)?.unwrap_or_default();
    let top: Vec<String> = std::fs::read_dir(dir).into_iter().flatten().flatten().filter_map(|e| e.file_name().to_str().map(str::to_string)).collect();
    let gone = |n: &str| removal.files.iter().any(|f| f.parent() == Some(dir) && f.file_name().is_some_and(|f| f == n));
    let input = |n: &str| {
        removal
            .kept_inputs
            .iter()
            .chain(protected)
            .any(|f| f.parent().is_some_and(|p| crate::io::manifest::same_dir(p, dir)) && f.file_name().is_some_and(|f| f == n))
    };
    let remaining: Vec<String> = top.iter().filter(|n| !gone(n) && !input(n) && n.as_str() != crate::io::lock::LOCK_FILE).cloned().collect();
    let left = held_names(remaining);
    if left != Held::Nothing {
        return Err(IoError::new(
            dir,
            format!(
                "holds {} that no sinterdem command recorded as its outputs ({MANIFEST} {}); sinterdem removes only the files it recorded: remove them yourself, or choose another --out",
                left.describe(),
                if dir.join(MANIFEST).exists() { "does not list them" } else { "is missing: written by an older sinterdem, or not by sinterdem" }
            ),
        ));
    }
    let mut c = Cleared::default();
    for f in &removal.files {
        match std::fs::remove_file(f) {
            Ok(()) => c.files += usize::from(f.file_name().is_none_or(|n| n != MANIFEST)),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(IoError::new(f, e)),
        }
    }
    for d in &removal.dirs {
        // only a folder left empty goes: one holding anything else is the user's
        if std::fs::remove_dir(d).is_ok() {
            c.dirs += 1;
        }
    }
    for e in std::fs::read_dir(dir).into_iter().flatten().flatten() {
        let name = e.file_name().to_string_lossy().to_string();
        if name != crate::io::lock::LOCK_FILE {
            c.kept.push(if e.file_type().is_ok_and(|t| t.is_dir()) { format!("{name}/") } else { name });
        }
    }
    c.kept.sort();
    Ok(c)
}

/// The fingerprint of a run's case: SHA-256 (hex) of the resolved case (includes expanded,
/// overrides applied, defaults such as `time.end` filled in) as TOML text, and of every file the
/// case names (`io::inputs`). Two runs with the same fingerprint compute the same thing.
pub fn case_fingerprint(case: &toml::Value, base: &Path) -> String {
    let mut h = Sha256::new();
    h.update(toml::to_string(case).unwrap_or_default().as_bytes());
    for (key, path) in crate::io::inputs::referenced_files(case, base) {
        h.update(key.as_bytes());
        if let Ok((bytes, sha)) = crate::io::inputs::digest(&path) {
            h.update(bytes.to_le_bytes());
            h.update(sha.as_bytes());
        }
    }
    h.finalize().iter().map(|b| format!("{b:02x}")).collect()
}

/// The run marker's content.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
struct Marker {
    kind: String,
    case_sha256: String,
    sinterdem: String,
}

/// Writes `dir/run.json` (atomically): this run's kind and case fingerprint.
pub fn write_marker(dir: &Path, kind: &str, fingerprint: &str) -> Result<(), IoError> {
    let m = Marker { kind: kind.into(), case_sha256: fingerprint.into(), sinterdem: env!("CARGO_PKG_VERSION").into() };
    let path = dir.join(RUN_MARKER);
    let text = serde_json::to_string_pretty(&m).map_err(|e| IoError::new(&path, e))?;
    crate::io::write_atomic(&path, &(text + "\n"))
}

/// Whether `dir/run.json` names the case fingerprint `fingerprint` (a rerun of the same case).
fn same_case(dir: &Path, fingerprint: &str) -> bool {
    std::fs::read_to_string(dir.join(RUN_MARKER)).ok().and_then(|t| serde_json::from_str::<Marker>(&t).ok()).is_some_and(|m| m.case_sha256 == fingerprint)
}

/// Which earlier outputs a command may continue without `--force`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Claimant {
    /// `run`, `generate`, `rve`: nothing; every earlier output needs `--force`.
    Run,
    /// `study`, `titanium`: its own study directory (a rerun continues it).
    Study,
    /// `calibrate`: its own calibration directory (a rerun reuses the runs of its generation
    /// studies and rewrites its results).
    Calibration,
}

/// Claims `dir` for a command before it writes its first file (the caller holds the directory's
/// lock): refuses a directory holding another command's outputs unless `force`, and with `force`
/// removes them ([`clear`]: the files its output manifest lists, never `protected`, the files the
/// command reads). A run (`fingerprint`: its [`case_fingerprint`]) into a directory whose run
/// marker names the same case is a rerun of that case: the earlier outputs are removed as with
/// `force`. The directory's output manifest is then opened (`crate::io::manifest::begin`), before
/// anything else is written. Returns the log line of what was removed, if anything.
pub fn claim(dir: &Path, who: Claimant, force: bool, fingerprint: Option<&str>, protected: &[PathBuf]) -> Result<Option<String>, IoError> {
    let h = held(dir);
    if let (Held::Run(_), Some(fp), false) = (&h, fingerprint, force)
        && same_case(dir, fp)
    {
        let c = clear(dir, protected)?;
        crate::io::manifest::begin(dir, false)?;
        return Ok(Some(format!(
            "a rerun of the same case ({RUN_MARKER}: the same resolved case and input files): {}",
            c.note(&h).trim_start_matches("--force: ")
        )));
    }
    let own = match (&h, who) {
        (Held::Nothing, _) => {
            crate::io::manifest::begin(dir, true)?;
            return Ok(None);
        }
        (Held::Study(_), Claimant::Study) => true,
        (Held::Calibration(_), Claimant::Calibration) => true,
        _ => false,
    };
    if own && !force {
        crate::io::manifest::begin(dir, true)?;
        return Ok(None);
    }
    if !force {
        let command = match who {
            Claimant::Run => "this run",
            Claimant::Study => "this study",
            Claimant::Calibration => "this calibration",
        };
        return Err(IoError::new(
            dir,
            format!("holds {}; {command} would mix its files with them: choose another --out, or add --force to remove them first", h.describe()),
        ));
    }
    let c = clear(dir, protected)?;
    crate::io::manifest::begin(dir, false)?;
    Ok(Some(c.note(&h)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::manifest;

    fn dir(name: &str) -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!("sinterdem-outdir-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    /// Writes `names` in `d` as a command recording them would.
    fn written(d: &Path, names: &[&str]) {
        for f in names {
            manifest::record(&d.join(f)).unwrap();
            std::fs::write(d.join(f), "x").unwrap();
        }
    }

    #[test]
    fn a_run_directory_is_refused_then_cleared_with_force_keeping_every_unrecorded_file() {
        let d = dir("run");
        assert_eq!(claim(&d, Claimant::Run, false, None, &[]).unwrap(), None, "an empty directory is free");
        // a run refused at its start leaves its log and input fingerprints only: not a result
        written(&d, &["log.txt", "inputs.json"]);
        assert_eq!(held(&d), Held::Nothing);
        written(&d, &["summary.json", "particles_000000.vtu", "particles_000001.vtu", "particles.pvd", "series.csv"]);
        std::fs::rename(d.join("series.csv"), d.join("series.csv.tmp42")).unwrap();
        manifest::end(&d);
        // the user's: a case file, a folder, a folder holding a summary.json
        std::fs::write(d.join("case.toml"), "x").unwrap();
        std::fs::create_dir_all(d.join("runs/0000")).unwrap();
        std::fs::write(d.join("runs/0000/summary.json"), "{}").unwrap();
        std::fs::create_dir_all(d.join("notes")).unwrap();
        let err = claim(&d, Claimant::Run, false, None, &[]).unwrap_err().to_string();
        assert!(err.contains("the outputs of a run (summary.json, 3 snapshot files)") && err.contains("--force"), "{err}");
        // a study or calibration does not continue a run's directory either
        assert!(claim(&d, Claimant::Study, false, None, &[]).is_err() && claim(&d, Claimant::Calibration, false, None, &[]).is_err());
        let note = claim(&d, Claimant::Run, true, None, &[]).unwrap().unwrap();
        manifest::end(&d);
        assert!(note.contains("7 files and 0 directories") && note.contains("kept case.toml, notes/, runs/"), "{note}");
        let mut left: Vec<String> = std::fs::read_dir(&d).unwrap().flatten().map(|e| e.file_name().to_string_lossy().to_string()).collect();
        left.sort();
        assert_eq!(left, ["case.toml", "notes", "outputs.json", "runs"]);
        assert!(d.join("runs/0000/summary.json").exists());
        assert_eq!(held(&d), Held::Nothing);
        // run files no manifest lists: refused, nothing removed
        std::fs::write(d.join("summary.json"), "{}").unwrap();
        let err = claim(&d, Claimant::Run, true, None, &[]).unwrap_err().to_string();
        assert!(err.contains("no sinterdem command recorded") && err.contains("does not list them"), "{err}");
        assert!(d.join("summary.json").exists() && d.join("case.toml").exists());
        let _ = std::fs::remove_dir_all(&d);
    }

    #[test]
    fn a_rerun_of_the_same_case_replaces_its_outputs_keeping_its_inputs_and_another_case_is_refused() {
        let d = dir("same");
        let case: toml::Value = toml::Value::Table("kind = \"heat\"\n[time]\nend = 10.0\n".parse().unwrap());
        let fp = case_fingerprint(&case, &d);
        assert_eq!(claim(&d, Claimant::Run, false, Some(&fp), &[]).unwrap(), None);
        write_marker(&d, "heat", &fp).unwrap();
        written(&d, &["summary.json", "particles_000003.vtu", "packing.csv"]);
        manifest::end(&d);
        let other: toml::Value = toml::Value::Table("kind = \"heat\"\n[time]\nend = 11.0\n".parse().unwrap());
        let e = claim(&d, Claimant::Run, false, Some(&case_fingerprint(&other, &d)), &[]).unwrap_err().to_string();
        assert!(e.contains("--force"), "{e}");
        // the earlier run wrote packing.csv, which this run reads: kept
        let note = claim(&d, Claimant::Run, false, Some(&fp), &[d.join("packing.csv")]).unwrap().unwrap();
        manifest::end(&d);
        assert!(note.starts_with("a rerun of the same case") && note.contains("3 files") && note.contains("packing.csv"), "{note}");
        assert_eq!(held(&d), Held::Run(vec!["packing.csv".into()]));
        assert!(!d.join("particles_000003.vtu").exists() && !d.join(RUN_MARKER).exists() && d.join("packing.csv").exists());
        let _ = std::fs::remove_dir_all(&d);
    }

    #[test]
    fn a_study_and_a_calibration_continue_their_own_directories_only() {
        let d = dir("study");
        std::fs::write(d.join("plan.json"), "[]").unwrap();
        assert_eq!(claim(&d, Claimant::Study, false, None, &[]).unwrap(), None);
        manifest::end(&d);
        assert!(claim(&d, Claimant::Run, false, None, &[]).unwrap_err().to_string().contains("the outputs of a study (plan.json)"));
        assert!(claim(&d, Claimant::Calibration, false, None, &[]).is_err());
        let c = dir("calibration");
        assert_eq!(claim(&c, Claimant::Calibration, false, None, &[]).unwrap(), None);
        written(&c, &["residuals.csv", "calibration.json"]);
        manifest::end(&c);
        assert_eq!(claim(&c, Claimant::Calibration, false, None, &[]).unwrap(), None, "continued");
        manifest::end(&c);
        assert!(claim(&c, Claimant::Run, false, None, &[]).is_err() && claim(&c, Claimant::Study, false, None, &[]).is_err());
        assert!(claim(&c, Claimant::Calibration, true, None, &[]).unwrap().is_some());
        manifest::end(&c);
        assert_eq!(held(&c), Held::Nothing);
        let _ = std::fs::remove_dir_all(&d);
        let _ = std::fs::remove_dir_all(&c);
    }
}
