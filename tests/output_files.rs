//! The files of a heat run: summary keys, one series row per step, VTU/PVD snapshots that are
//! well-formed XML with the right counts, and (with the `h5` feature) HDF5 datasets that read back.

use sinterdem::config::load_case;
use sinterdem::heat::run::{prepare, run};
use std::path::Path;

#[test]
fn heat_run_writes_summary_series_and_snapshots() {
    let sets: Vec<String> = ["particles.cells=[2, 2, 3]", "time.end=10", "time.dt=1", "output.snapshots=3"].iter().map(|s| s.to_string()).collect();
    let v = load_case(Path::new("cases/hot-plate.toml"), &sets).unwrap();
    let prep = prepare(v, Path::new("cases")).unwrap();
    let (n, m) = (prep.scene.particles.len(), prep.pipes.pairs.len());
    let dir = std::env::temp_dir().join(format!("sinterdem-out-{}", std::process::id()));
    let s = run(prep, &dir, false, &mut |_| {}).unwrap();
    for key in ["final_time_s", "steps", "wall_seconds", "energy_balance_rel", "mean_temperature_K", "min_temperature_K", "max_temperature_K"] {
        assert!(s[key].is_number(), "summary lacks {key}");
    }
    assert_eq!(s["steps"].as_u64(), Some(10));
    let series = std::fs::read_to_string(dir.join("series.csv")).unwrap();
    assert_eq!(series.lines().count(), 11);
    assert!(series.starts_with("time_s,dt_s,mean_temperature_K"));
    let pvd = std::fs::read_to_string(dir.join("particles.pvd")).unwrap();
    assert_eq!(pvd.matches("<DataSet").count(), 3);
    for k in 0..3 {
        let p = std::fs::read_to_string(dir.join(format!("particles_{k:06}.vtu"))).unwrap();
        assert!(p.contains(&format!("NumberOfPoints=\"{n}\" NumberOfCells=\"{n}\"")));
        assert!(p.contains("Name=\"temperature_K\"") && p.contains("Name=\"radius_m\""));
        let c = std::fs::read_to_string(dir.join(format!("contacts_{k:06}.vtu"))).unwrap();
        assert!(c.contains(&format!("NumberOfCells=\"{m}\"")));
        assert!(c.contains("Name=\"neck_radius_m\"") && c.contains("Name=\"conductance_W_per_K\""));
        assert!(c.trim_end().ends_with("</VTKFile>"));
    }
    #[cfg(feature = "h5")]
    {
        let f = hdf5_metno::File::open(dir.join("sinterdem.h5")).unwrap();
        let g = f.group("snapshots/000002").unwrap();
        let t: f64 = g.attr("time").unwrap().read_scalar().unwrap();
        assert_eq!(t, 10.0);
        let temp: Vec<f64> = g.dataset("temperature").unwrap().read_raw().unwrap();
        assert_eq!(temp.len(), n);
        assert!((temp.iter().sum::<f64>() / n as f64 - s["mean_temperature_K"].as_f64().unwrap()).abs() < 1e-9);
        let pos = g.dataset("position").unwrap();
        assert_eq!(pos.shape(), vec![n, 3]);
    }
    let _ = std::fs::remove_dir_all(&dir);
}
