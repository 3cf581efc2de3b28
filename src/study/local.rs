//! The embedded local engine: `jobs` runs at a time in this process, each inside its own rayon
//! pool of `threads` threads, taking runs in plan order from a shared counter. A progress bar over
//! runs (with an ETA from the runs done so far) on a terminal; silent otherwise.

use super::store::{self, PlannedRun};
use crate::error::{Error, SolveError};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Default runs at a time: the cores divided by the threads of each run.
pub fn default_jobs(threads: usize) -> usize {
    let cores = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1);
    (cores / threads.max(1)).max(1)
}

/// Executes the runs `todo` (plan indices); returns how many were executed.
pub fn run(dir: &Path, plan: &[PlannedRun], todo: &[usize], jobs: usize, threads: usize, progress: bool, log: &mut dyn FnMut(&str)) -> Result<usize, Error> {
    if todo.is_empty() {
        return Ok(0);
    }
    let jobs = if jobs == 0 { default_jobs(threads) } else { jobs }.min(todo.len());
    log(&format!("local engine: {} runs, {jobs} at a time, {threads} thread{} each", todo.len(), if threads == 1 { "" } else { "s" }));
    let on = progress && crate::io::progress::bars_allowed();
    let bar = on.then(|| {
        let b = crate::io::progress::add_bar(ProgressBar::new(todo.len() as u64));
        b.set_style(
            // one line at any terminal width (the message is cut to what is left: issue 39)
            ProgressStyle::with_template("{bar:24.cyan/blue} {pos}/{len} runs, ETA {eta} {wide_msg}").unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        b
    });
    let next = AtomicUsize::new(0);
    let failed = AtomicUsize::new(0);
    let pools: Vec<rayon::ThreadPool> = (0..jobs)
        .map(|_| rayon::ThreadPoolBuilder::new().num_threads(threads.max(1)).build())
        .collect::<Result<_, _>>()
        .map_err(|e| SolveError::new("study engine", format!("cannot start a thread pool: {e}")))?;
    std::thread::scope(|s| {
        for pool in &pools {
            let (next, failed, bar) = (&next, &failed, &bar);
            s.spawn(move || {
                loop {
                    // Ctrl-C/SIGTERM: the runs in progress stop with their outputs, no new run starts
                    if crate::interrupt::requested() {
                        break;
                    }
                    let k = next.fetch_add(1, Ordering::Relaxed);
                    let Some(&i) = todo.get(k) else { break };
                    let rec = pool.install(|| store::execute(dir, &plan[i]));
                    if !rec.ok() {
                        failed.fetch_add(1, Ordering::Relaxed);
                    }
                    if let Some(b) = bar {
                        let f = failed.load(Ordering::Relaxed);
                        if f > 0 {
                            b.set_message(format!("({f} failed)"));
                        }
                        b.inc(1);
                    }
                }
            });
        }
    });
    if let Some(b) = &bar {
        b.finish_and_clear();
    }
    Ok(todo.len())
}
