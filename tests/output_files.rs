//! The files of a heat run: summary keys, one series row per step, binary VTU/PVD snapshots with
//! the right counts and array names, and (with the `h5` feature) the H5MD-layout HDF5 file.

use sinterdem::config::load_case;
use sinterdem::kinds::heat::run;
use sinterdem::scene::prepare;
use std::path::Path;

mod common;

#[test]
fn heat_run_writes_summary_series_and_snapshots() {
    let sets: Vec<String> = ["particles.cells=[2, 2, 3]", "time.end=10", "time.dt=1", "output.snapshots=3"].iter().map(|s| s.to_string()).collect();
    let v = load_case(Path::new("cases/hot-plate.toml"), &sets).unwrap();
    let prep = prepare(v, Path::new("cases")).unwrap();
    let (n, m) = (prep.scene.particles.len(), prep.pipes.pairs.len());
    let dir = common::tmp_dir("out");
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
        assert!(p.contains("compressor=\"vtkZLibDataCompressor\"") && p.contains("header_type=\"UInt64\""));
        for name in ["temperature_K", "radius_m", "id", "coordination"] {
            assert!(p.contains(&format!("Name=\"{name}\"")), "particles lack {name}");
        }
        assert!(!p.contains("format=\"ascii\""), "binary arrays only");
        let c = std::fs::read_to_string(dir.join(format!("contacts_{k:06}.vtu"))).unwrap();
        assert!(c.contains(&format!("NumberOfCells=\"{m}\"")));
        for name in ["neck_radius_m", "conductance_W_per_K", "particle_a", "particle_b"] {
            assert!(c.contains(&format!("Name=\"{name}\"")), "contacts lack {name}");
        }
        assert!(c.trim_end().ends_with("</VTKFile>"));
    }
    #[cfg(feature = "h5")]
    {
        // H5MD layout (docs/outputs.md)
        let f = hdf5_metno::File::open(dir.join("sinterdem.h5")).unwrap();
        let unit = |ds: &hdf5_metno::Dataset| -> String { ds.attr("unit").unwrap().read_scalar::<hdf5_metno::types::VarLenUnicode>().unwrap().to_string() };
        let creator = f.group("h5md/creator").unwrap();
        assert_eq!(creator.attr("name").unwrap().read_scalar::<hdf5_metno::types::VarLenUnicode>().unwrap().as_str(), "sinterdem");
        let time: Vec<f64> = f.dataset("particles/all/temperature/time").unwrap().read_raw().unwrap();
        assert_eq!(time, vec![0.0, 5.0, 10.0]);
        let tv = f.dataset("particles/all/temperature/value").unwrap();
        assert_eq!(tv.shape(), vec![3, n]);
        assert_eq!(unit(&tv), "K");
        assert!(tv.is_chunked() && tv.filters().iter().any(|x| matches!(x, hdf5_metno::filters::Filter::Deflate(_))));
        let temp: Vec<f64> = tv.read_raw().unwrap();
        let last = &temp[2 * n..];
        assert!((last.iter().sum::<f64>() / n as f64 - s["mean_temperature_K"].as_f64().unwrap()).abs() < 1e-9);
        let pos = f.dataset("particles/all/position/value").unwrap();
        assert_eq!(pos.shape(), vec![3, n, 3]);
        assert_eq!(unit(&pos), "m");
        let count: Vec<i64> = f.dataset("contacts/count/value").unwrap().read_raw().unwrap();
        assert_eq!(count, vec![m as i64; 3]);
        assert_eq!(f.dataset("contacts/pairs/value").unwrap().shape(), vec![3, m, 2]);
        assert_eq!(unit(&f.dataset("contacts/conductance/value").unwrap()), "W K-1");
        // the series, the summary and the case are in the file too
        let obs: Vec<f64> = f.dataset("observables/mean_temperature/value").unwrap().read_raw().unwrap();
        assert_eq!(obs.len(), 10);
        let case = f.dataset("parameters/case_toml").unwrap().read_scalar::<hdf5_metno::types::VarLenUnicode>().unwrap();
        assert!(case.as_str().contains("[time]"));
        let json = f.dataset("summary/json").unwrap().read_scalar::<hdf5_metno::types::VarLenUnicode>().unwrap();
        assert!(json.as_str().contains("energy_balance_rel"));
    }
    let _ = std::fs::remove_dir_all(&dir);
}
