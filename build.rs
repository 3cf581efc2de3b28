//! Build script: with the `hypre` feature, finds and links the system hypre library (libHYPRE)
//! and the MPI library it was built against (docs/coupled.md "hypre's BoomerAMG against our AMG"). Without the feature it
//! does nothing.
//!
//! Search order: `HYPRE_DIR` (a prefix with lib/ and include/) or `HYPRE_LIB_DIR`; pkg-config
//! `hypre`; the Debian/Ubuntu multiarch and the usual system library folders. MPI: `MPI_LIB_DIR`,
//! pkg-config `ompi-c` / `mpich`, then the folder that holds libHYPRE.

use std::path::{Path, PathBuf};
use std::process::Command;

fn pkg_config_libdirs(name: &str) -> Option<Vec<PathBuf>> {
    let out = Command::new("pkg-config").args(["--libs-only-L", name]).output().ok()?;
    if !out.status.success() {
        return None;
    }
    let dirs: Vec<PathBuf> = String::from_utf8_lossy(&out.stdout).split_whitespace().filter_map(|t| t.strip_prefix("-L")).map(PathBuf::from).collect();
    Some(dirs)
}

fn has_lib(dir: &Path, name: &str) -> bool {
    dir.join(format!("lib{name}.so")).exists() || dir.join(format!("lib{name}.a")).exists()
}

fn system_dirs() -> Vec<PathBuf> {
    let mut v = Vec::new();
    if let Ok(arch) = std::env::var("CARGO_CFG_TARGET_ARCH") {
        v.push(PathBuf::from(format!("/usr/lib/{arch}-linux-gnu")));
    }
    for d in ["/usr/lib64", "/usr/lib", "/usr/local/lib", "/usr/local/lib64"] {
        v.push(PathBuf::from(d));
    }
    v
}

fn find(name: &str, env_dir: Option<PathBuf>, pkgs: &[&str], extra: &[PathBuf]) -> Option<PathBuf> {
    let mut candidates: Vec<PathBuf> = env_dir.into_iter().collect();
    for p in pkgs {
        candidates.extend(pkg_config_libdirs(p).unwrap_or_default());
    }
    candidates.extend(extra.iter().cloned());
    candidates.extend(system_dirs());
    candidates.into_iter().find(|d| has_lib(d, name))
}

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    for v in ["HYPRE_DIR", "HYPRE_LIB_DIR", "MPI_LIB_DIR", "PKG_CONFIG_PATH"] {
        println!("cargo:rerun-if-env-changed={v}");
    }
    if std::env::var_os("CARGO_FEATURE_HYPRE").is_none() {
        return;
    }
    let env_dir = std::env::var_os("HYPRE_LIB_DIR").map(PathBuf::from).or_else(|| std::env::var_os("HYPRE_DIR").map(|d| PathBuf::from(d).join("lib")));
    let Some(hypre) = find("HYPRE", env_dir, &["hypre", "HYPRE"], &[]) else {
        panic!(
            "the `hypre` feature needs the hypre library (libHYPRE.so), which was not found: install it \
             (Debian/Ubuntu: `apt-get install libhypre-dev`) or set HYPRE_DIR (a prefix with lib/) or HYPRE_LIB_DIR; \
             or build without `--features hypre` (docs/coupled.md \"hypre's BoomerAMG against our AMG\")"
        );
    };
    let mpi_env = std::env::var_os("MPI_LIB_DIR").map(PathBuf::from);
    let Some(mpi) = find("mpi", mpi_env, &["ompi-c", "mpich"], std::slice::from_ref(&hypre)) else {
        panic!(
            "the `hypre` feature needs the MPI library hypre was built with (libmpi.so), which was not found in \
             {} or the system folders: install it (Debian: `apt-get install libopenmpi-dev`, pulled in by libhypre-dev) \
             or set MPI_LIB_DIR",
            hypre.display()
        );
    };
    // the communicator handles of src/mechanics/hypre.rs are Open MPI's (ompi_mpi_comm_self)
    if !has_lib(&mpi, "open-pal") {
        println!(
            "cargo:warning=hypre: the MPI in {} does not look like Open MPI; src/mechanics/hypre.rs uses Open MPI's MPI_COMM_SELF symbol (ompi_mpi_comm_self) and will not link with another MPI",
            mpi.display()
        );
    }
    println!("cargo:rustc-link-search=native={}", hypre.display());
    if mpi != hypre {
        println!("cargo:rustc-link-search=native={}", mpi.display());
    }
    println!("cargo:rustc-link-lib=dylib=HYPRE");
    println!("cargo:rustc-link-lib=dylib=mpi");
}
