//! Packing generation, import and case validation.
use nalgebra::Vector3;
use sinterdem::kinds::generate as packing;
use sinterdem::packing::{ImportFormat, import_str};

mod common;

fn case(text: &str) -> toml::Value {
    toml::Value::Table(text.parse::<toml::Table>().unwrap())
}

const SMALL: &str = r#"
kind = "generate"
[packing]
particles = 200
seed = 7
target_solid_fraction = 0.55
box = [1.0, 1.0, 1.0]
[packing.size]
distribution = "uniform"
mean_diameter = 50e-6
spread = 0.1
"#;

#[test]
fn small_packing_is_stress_free_at_the_target_and_reproducible_from_the_seed() {
    let (a, b, c) = (common::tmp_dir("seed-a"), common::tmp_dir("seed-b"), common::tmp_dir("seed-c"));
    let sa = packing::generate_case(&case(SMALL), &a, false).unwrap();
    let sb = packing::generate_case(&case(SMALL), &b, false).unwrap();
    let csv_a = std::fs::read_to_string(a.join("packing.csv")).unwrap();
    assert_eq!(csv_a, std::fs::read_to_string(b.join("packing.csv")).unwrap(), "same seed, same packing");
    assert_eq!(sa.steps, sb.steps);
    let other = SMALL.replace("seed = 7", "seed = 8");
    packing::generate_case(&case(&other), &c, false).unwrap();
    assert_ne!(csv_a, std::fs::read_to_string(c.join("packing.csv")).unwrap());
    // physics of the result
    assert!(sa.thresholds_met);
    assert!(sa.max_overlap_rel < 1e-3, "{sa:?}");
    assert!((sa.solid_fraction - 0.55).abs() < 0.01, "{sa:?}");
    assert!(sa.coordination_mean > 3.0, "{sa:?}");
    // the CSV reads back through the importer; the spheres fill the reported fraction of the box
    let p = sinterdem::packing::import(&a.join("packing.csv"), ImportFormat::Csv).unwrap();
    assert_eq!(p.radii.len(), 200);
    let vp: f64 = p.radii.iter().map(|&r| sinterdem::units::sphere_volume(r)).sum();
    let vbox: f64 = sa.box_size.iter().product();
    assert!((vp / vbox - sa.solid_fraction).abs() < 1e-8);
    for (x, &r) in p.positions.iter().zip(&p.radii) {
        for k in 0..3 {
            assert!(x[k] - r > -1e-3 * sa.mean_radius && x[k] + r < sa.box_size[k] + 1e-3 * sa.mean_radius);
        }
    }
    for f in ["summary.json", "packing.vtu", "laminae.csv", "laminae.png", "size_distribution.csv"] {
        assert!(a.join(f).exists(), "{f}");
    }
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(a.join("summary.json")).unwrap()).unwrap();
    for k in ["solid_fraction", "coordination_mean", "max_overlap_rel", "particles"] {
        assert!(json.get(k).is_some(), "{k}");
    }
    for d in [a, b, c] {
        let _ = std::fs::remove_dir_all(d);
    }
}

#[test]
fn laminae_of_a_simple_cubic_lattice_have_the_lattice_density() {
    // spheres of radius r on a cubic lattice of spacing a: every lamina one spacing wide that is
    // centred on a layer holds one sphere per cell: density (4/3)π r³/a³ (eq. 48).
    let (r, a) = (0.4, 1.0);
    let mut pos = Vec::new();
    for i in 0..6 {
        for j in 0..6 {
            for k in 0..6 {
                pos.push(Vector3::new(i as f64 + 0.5, j as f64 + 0.5, k as f64 + 0.5) * a);
            }
        }
    }
    let rad = vec![r; pos.len()];
    let hi = Vector3::repeat(6.0 * a);
    for axis in 0..3 {
        let l = sinterdem::packing::report::laminae(&pos, &rad, &Vector3::zeros(), &hi, axis, a, 0.0);
        assert_eq!(l.density.len(), 6);
        for d in &l.density {
            assert!((d - sinterdem::units::sphere_volume(r) / (a * a * a)).abs() < 1e-12);
        }
    }
}

#[test]
fn bad_case_values_are_rejected_naming_the_key() {
    let cases = [
        ("target_solid_fraction = 0.55", "target_solid_fraction = 0.9", "packing.target_solid_fraction"),
        ("spread = 0.1", "spread = -0.1", "packing.size.spread"),
        ("particles = 200", "particles = 1", "packing.particles"),
        ("box = [1.0, 1.0, 1.0]", "box = [1.0, 0.0, 1.0]", "packing.box.1"),
        ("box = [1.0, 1.0, 1.0]", "box = [1.0, 1.0]", "packing.box"),
        ("spread = 0.1", "spread = 0.1\nstd_diameter = 1e-6", "packing.size.std_diameter"),
        ("distribution = \"uniform\"", "distribution = \"lognormal\"", "packing.size.distribution"),
        ("spread = 0.1", "spread = 0.1\nsprad = 3", "sprad"),
        ("kind = \"generate\"", "kind = \"run\"", "kind"),
        ("mean_diameter = 50e-6", "mean_diameter = -50e-6", "packing.size.mean_diameter"),
    ];
    for (from, to, key) in cases {
        let text = SMALL.replace(from, to);
        let e = packing::check_generate_case(&case(&text)).err().unwrap_or_else(|| panic!("{to} accepted")).to_string();
        assert!(e.contains(key), "{to}: {e}");
    }
    let normal = SMALL
        .replace("distribution = \"uniform\"\nmean_diameter = 50e-6\nspread = 0.1", "distribution = \"normal\"\nmean_diameter = 50e-6\nstd_diameter = 30e-6");
    let e = packing::check_generate_case(&case(&normal)).unwrap_err().to_string();
    assert!(e.contains("packing.size.truncate"), "{e}");
    let tab = SMALL.replace(
        "distribution = \"uniform\"\nmean_diameter = 50e-6\nspread = 0.1",
        "distribution = \"tabulated\"\ndiameters = [40e-6, 30e-6]\ncumulative = [0.0, 1.0]",
    );
    let e = packing::check_generate_case(&case(&tab)).unwrap_err().to_string();
    assert!(e.contains("packing.size.diameters.1"), "{e}");
    packing::check_generate_case(&case(SMALL)).unwrap();
}

#[test]
fn import_reads_the_three_formats_and_names_bad_lines() {
    let csv = "# a comment\nx,y,z,r,material,temperature\n0,0,0,1e-5,0,300\n3e-5,0,0,1.5e-5,1,310\n";
    let p = import_str(csv, ImportFormat::Csv, "a.csv").unwrap();
    assert_eq!(p.radii, vec![1e-5, 1.5e-5]);
    assert_eq!(p.materials, Some(vec![0, 1]));
    assert_eq!(p.temperatures, Some(vec![300.0, 310.0]));
    let dump = "ITEM: TIMESTEP\n0\nITEM: NUMBER OF ATOMS\n2\nITEM: BOX BOUNDS pp pp pp\n0 1\n0 1\n0 1\nITEM: ATOMS id type x y z radius\n1 1 0.1 0.2 0.3 0.01\n2 2 0.4 0.5 0.6 0.02\n";
    let p = import_str(dump, ImportFormat::Liggghts, "d.dump").unwrap();
    assert_eq!(p.positions[1], Vector3::new(0.4, 0.5, 0.6));
    assert_eq!(p.materials, Some(vec![0, 1]));
    let yade = "#format x_y_z_r\n0.1 0.2 0.3 0.01\n0.4 0.5 0.6 0.02\n";
    assert_eq!(import_str(yade, ImportFormat::Yade, "y.txt").unwrap().radii, vec![0.01, 0.02]);

    let short_line = dump.replace("2 2 0.4 0.5 0.6 0.02", "2 2 0.4 0.5 0.6");
    let no_radius = dump.replace("id type x y z radius", "id type x y z");
    let bad = [
        (ImportFormat::Csv, "x,y,z,r\n0,0,0,1e-5\n0,0,abc,1e-5\n", "line 3"),
        (ImportFormat::Csv, "x,y,z,r\n0,0,0,1e-5\n0,0,0\n", "line 3"),
        (ImportFormat::Csv, "x,y,z,r\n0,0,0,-1e-5\n", "line 2"),
        (ImportFormat::Csv, "a,b,c\n1,2,3\n", "line 1"),
        (ImportFormat::Liggghts, short_line.as_str(), "line 11"),
        (ImportFormat::Liggghts, no_radius.as_str(), "line 9"),
        (ImportFormat::Yade, "#format x_y_z_r\n0.1 0.2 0.3 0.01\n0.4 0.5 nan 0.02\n", "line 3"),
        (ImportFormat::Yade, "0.1 0.2 0.3\n", "line 1"),
    ];
    for (f, text, want) in bad {
        let e = import_str(text, f, "file").unwrap_err().to_string();
        assert!(e.contains(want) && e.contains("file"), "{f:?}: {e}");
    }
    assert!(import_str("", ImportFormat::Yade, "empty").unwrap_err().to_string().contains("no particles"));
    assert!("vtk".parse::<ImportFormat>().is_err());
}
