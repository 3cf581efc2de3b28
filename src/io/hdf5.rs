//! HDF5 snapshots (`DIR/sinterdem.h5`): one group `/snapshots/NNNNNN` per snapshot with datasets
//! `position` [m] (N×3), `radius` [m], `temperature` [K], `contacts` (M×2 particle indices) and
//! one dataset per contact array, and the attribute `time` [s].
//!
//! Needs the `h5` cargo feature (system library libhdf5, Debian package `libhdf5-dev`); without it
//! the writer reports [`H5Error::Disabled`] and the run logs [`DISABLED_MESSAGE`].

use super::Snapshot;
use crate::error::IoError;
use std::path::Path;

pub const DISABLED_MESSAGE: &str = "HDF5 output is off: this binary was built without the `h5` feature (build with `cargo build --release --features h5` after installing libhdf5-dev and pkg-config); VTU and CSV output are unaffected";

#[derive(Debug)]
pub enum H5Error {
    Disabled,
    Io(IoError),
}

/// Writes snapshots into one HDF5 file. The file is open only while a snapshot is written (created,
/// written, flushed, closed), so a run killed between snapshots leaves a consistent file that a
/// resumed run can reopen.
#[cfg(feature = "h5")]
pub struct H5Writer {
    path: std::path::PathBuf,
    /// What the reopening had to do, for the run's log.
    pub note: Option<String>,
}

#[cfg(feature = "h5")]
impl H5Writer {
    pub fn create(path: &Path) -> Result<Self, H5Error> {
        let err = |e: hdf5_metno::Error| H5Error::Io(IoError::new(path, e));
        let file = hdf5_metno::File::create(path).map_err(err)?;
        file.create_group("snapshots").map_err(err)?;
        file.close().map_err(err)?;
        Ok(H5Writer { path: path.to_path_buf(), note: None })
    }

    /// Reopens the file of an interrupted run, removing the snapshots numbered `keep` and above
    /// (written after the checkpoint). A file that cannot be read (the run was killed while writing
    /// a snapshot) is moved to `<name>.damaged` and a new one started; `note` says so.
    pub fn reopen(path: &Path, keep: usize) -> Result<Self, H5Error> {
        if !path.exists() {
            return Self::create(path);
        }
        let trim = || -> Result<(), hdf5_metno::Error> {
            let file = hdf5_metno::File::open_rw(path)?;
            let g = file.group("snapshots")?;
            for name in g.member_names()? {
                if name.parse::<usize>().map(|k| k >= keep).unwrap_or(false) {
                    g.unlink(&name)?;
                }
            }
            drop(g);
            file.close()
        };
        match trim() {
            Ok(()) => Ok(H5Writer { path: path.to_path_buf(), note: None }),
            Err(e) => {
                let moved = path.with_extension("h5.damaged");
                std::fs::rename(path, &moved).map_err(|io| H5Error::Io(IoError::new(path, io)))?;
                let mut w = Self::create(path)?;
                w.note = Some(format!(
                    "warning: {} could not be reopened ({e}); moved to {} and a new file started: its snapshots before the checkpoint are in the VTU files only",
                    path.display(),
                    moved.display()
                ));
                Ok(w)
            }
        }
    }

    pub fn write(&mut self, index: usize, s: &Snapshot) -> Result<(), IoError> {
        let err = |e: hdf5_metno::Error| IoError::new(&self.path, e);
        let file = hdf5_metno::File::open_rw(&self.path).map_err(err)?;
        let g = file.group("snapshots").map_err(err)?.create_group(&format!("{index:06}")).map_err(err)?;
        g.new_attr::<f64>().create("time").map_err(err)?.write_scalar(&s.time).map_err(err)?;
        let pos: Vec<[f64; 3]> = s.position.iter().map(|p| [p.x, p.y, p.z]).collect();
        g.new_dataset_builder().with_data::<_, f64, ndarray::Ix2>(pos.as_slice()).create("position").map_err(err)?;
        g.new_dataset_builder().with_data(s.radius).create("radius").map_err(err)?;
        g.new_dataset_builder().with_data(s.temperature).create("temperature").map_err(err)?;
        g.new_dataset_builder().with_data::<_, u32, ndarray::Ix2>(s.contacts).create("contacts").map_err(err)?;
        for (name, v) in s.contact_data.iter().chain(s.particle_data.iter()) {
            g.new_dataset_builder().with_data(*v).create(*name).map_err(err)?;
        }
        drop(g);
        file.close().map_err(err)?;
        Ok(())
    }
}

#[cfg(not(feature = "h5"))]
pub struct H5Writer {
    pub note: Option<String>,
}

#[cfg(not(feature = "h5"))]
impl H5Writer {
    pub fn create(_path: &Path) -> Result<Self, H5Error> {
        Err(H5Error::Disabled)
    }

    pub fn reopen(_path: &Path, _keep: usize) -> Result<Self, H5Error> {
        Err(H5Error::Disabled)
    }

    pub fn write(&mut self, _index: usize, _s: &Snapshot) -> Result<(), IoError> {
        Ok(())
    }
}

/// Whether this binary writes HDF5.
pub const ENABLED: bool = cfg!(feature = "h5");
