//! The single-node SLURM cluster on localhost of the SLURM tests (`mod slurm_cluster;`):
//! `scripts/test-all.sh` starts it once and passes `SINTERDEM_SLURM_DIR`; a test run alone starts
//! (and, when done, stops) its own with `scripts/slurm-local.sh`. Where no cluster can be started
//! (not root, no apt-get), the test prints a SKIP line saying why and returns.
#![allow(dead_code)]

use std::path::PathBuf;
use std::process::Command;

pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

pub struct Cluster {
    pub dir: PathBuf,
    started_here: bool,
}

impl Cluster {
    /// The cluster's `slurm.conf` (for `SLURM_CONF`).
    pub fn conf(&self) -> PathBuf {
        self.dir.join("slurm.conf")
    }
}

impl Drop for Cluster {
    fn drop(&mut self) {
        if self.started_here {
            let _ = Command::new("bash").arg(repo().join("scripts/slurm-local.sh")).arg("stop").arg(&self.dir).status();
        }
    }
}

/// The cluster, or None after a SKIP line naming `what` (the test) and the reason. `tag` names
/// the directory of a cluster started here.
pub fn cluster(what: &str, tag: &str) -> Option<Cluster> {
    if let Ok(d) = std::env::var("SINTERDEM_SLURM_DIR") {
        return Some(Cluster { dir: PathBuf::from(d), started_here: false });
    }
    if let Ok(reason) = std::env::var("SINTERDEM_SLURM_SKIP") {
        eprintln!("SKIP {what}: {reason}");
        return None;
    }
    let dir = std::env::temp_dir().join(format!("sinterdem-{tag}-{}", std::process::id()));
    let st = Command::new("bash").arg(repo().join("scripts/slurm-local.sh")).arg("start").arg(&dir).status().expect("bash runs");
    match st.code() {
        Some(0) => Some(Cluster { dir, started_here: true }),
        Some(77) => {
            eprintln!("SKIP {what}: scripts/slurm-local.sh could not start a cluster here (see its SKIP line)");
            None
        }
        _ => panic!("scripts/slurm-local.sh start {} failed ({st})", dir.display()),
    }
}
