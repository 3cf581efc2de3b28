//! One writer per output directory (docs/outputs.md "Guarantees"): every command that writes an
//! output directory (`run`, `resume`, `study`, `calibrate`, `generate`) holds an advisory lock on
//! `DIR/.sinterdem.lock` while it writes. A second writer is refused at once with the holder's pid,
//! command and start time. The lock is the operating system's (`File::try_lock`, flock on Unix): it
//! is released when the holder exits for any reason, SIGKILL included, so a lock file left by a
//! dead process is taken over by the next writer (the log says so). The file itself stays: deleting
//! it on exit would let two later writers lock two different files.

use crate::error::IoError;
use std::fs::{File, OpenOptions, TryLockError};
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

/// File name of the lock inside an output directory.
pub const LOCK_FILE: &str = ".sinterdem.lock";

thread_local! {
    /// The command a run opened on this thread is named by in its lock (None: the kind's own).
    static COMMAND: std::cell::Cell<Option<&'static str>> = const { std::cell::Cell::new(None) };
}

/// Runs `f` (which opens a run) with that run's lock naming `command`: `sinterdem rve` opens its
/// free run through the run's path, and its lock said "sinterdem run" (issue 38).
pub fn as_command<T>(command: &'static str, f: impl FnOnce() -> T) -> T {
    let before = COMMAND.with(|c| c.replace(Some(command)));
    let out = f();
    COMMAND.with(|c| c.set(before));
    out
}

/// The command set by [`as_command`] on this thread, else `default`.
pub fn command_or(default: &'static str) -> &'static str {
    COMMAND.with(|c| c.get()).unwrap_or(default)
}

/// A held output-directory lock; released on drop (and by the OS when the process dies).
#[derive(Debug)]
pub struct OutputLock {
    file: File,
    path: PathBuf,
    /// What the lock file said when this writer took it over from a process that is gone (None:
    /// the file was new or empty).
    pub taken_over: Option<String>,
}

impl OutputLock {
    /// Locks `dir` (created if missing) for `command` (e.g. "run", "study"). Refuses with an
    /// [`IoError`] naming the holder when another process (or another lock in this process) holds it.
    pub fn acquire(dir: &Path, command: &str) -> Result<OutputLock, IoError> {
        crate::io::ensure_dir(dir)?;
        let path = dir.join(LOCK_FILE);
        let mut file = OpenOptions::new().read(true).write(true).create(true).truncate(false).open(&path).map_err(|e| IoError::new(&path, e))?;
        match file.try_lock() {
            Ok(()) => {}
            Err(TryLockError::WouldBlock) => {
                let holder = read_holder(&mut file);
                let who = if holder.is_empty() { "another sinterdem process".to_string() } else { holder };
                return Err(IoError::new(
                    dir,
                    format!("is being written by {who}; one writer per output directory: wait for it to finish, stop it, or choose another --out"),
                ));
            }
            Err(TryLockError::Error(e)) => return Err(IoError::new(&path, format!("cannot take the output-directory lock: {e}"))),
        }
        let previous = read_holder(&mut file);
        let taken_over = (!previous.is_empty()).then_some(previous);
        let started = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map(|d| d.as_secs()).unwrap_or(0);
        let text = format!("pid {} · sinterdem {command} · started at unix time {started} s\n", std::process::id());
        let written = file.set_len(0).and_then(|_| file.seek(SeekFrom::Start(0))).and_then(|_| file.write_all(text.as_bytes())).and_then(|_| file.flush());
        written.map_err(|e| IoError::new(&path, e))?;
        Ok(OutputLock { file, path, taken_over })
    }

    /// The lock file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// A log line for a lock taken over from a process that is gone (None: nothing to say).
    pub fn takeover_note(&self) -> Option<String> {
        self.taken_over.as_ref().map(|h| format!("output directory lock taken over from a process that is gone ({})", h.trim()))
    }
}

impl Drop for OutputLock {
    fn drop(&mut self) {
        // the holder line is cleared so that the next writer does not report a takeover after a
        // clean exit; the OS releases the lock when the file is closed
        let _ = self.file.set_len(0);
        // the directory's output manifest is closed with its lock (crate::io::manifest)
        if let Some(dir) = self.path.parent() {
            crate::io::manifest::end(dir);
        }
        let _ = self.file.unlock();
    }
}

/// The holder line of a lock file (empty when none was written).
fn read_holder(file: &mut File) -> String {
    let mut s = String::new();
    let _ = file.seek(SeekFrom::Start(0)).and_then(|_| file.read_to_string(&mut s));
    s.trim().to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("sinterdem-lock-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        d
    }

    #[test]
    fn a_second_writer_is_refused_with_the_holders_pid_and_may_lock_after_release() {
        let d = dir("second");
        let first = OutputLock::acquire(&d, "run").unwrap();
        assert!(first.taken_over.is_none());
        let err = OutputLock::acquire(&d, "study").unwrap_err().to_string();
        assert!(err.contains(&format!("pid {}", std::process::id())), "{err}");
        assert!(err.contains("sinterdem run") && err.contains("one writer per output directory"), "{err}");
        drop(first);
        let again = OutputLock::acquire(&d, "resume").unwrap();
        assert!(again.taken_over.is_none(), "a clean release is not a takeover");
        drop(again);
        let _ = std::fs::remove_dir_all(&d);
    }

    #[test]
    fn a_lock_file_left_by_a_dead_process_is_taken_over_and_reported() {
        let d = dir("stale");
        std::fs::create_dir_all(&d).unwrap();
        std::fs::write(d.join(LOCK_FILE), "pid 999999 · sinterdem run · started at unix time 1 s\n").unwrap();
        let lock = OutputLock::acquire(&d, "run").unwrap();
        let note = lock.takeover_note().unwrap();
        assert!(note.contains("pid 999999"), "{note}");
        drop(lock);
        let _ = std::fs::remove_dir_all(&d);
    }
}
