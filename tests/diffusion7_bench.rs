//! The work-precision benchmark runs end to end (the numbers are measured by `sinterdem bench pair`,
//! not asserted here beyond sanity): errors fall as the tolerance tightens.

use sinterdem::bench::diffusion7::{copper_spec, work_precision};
use sinterdem::models::ode::Method;

#[test]
fn work_precision_errors_fall_with_tolerance() {
    let spec = copper_spec().unwrap();
    let rows = work_precision(&spec, &Method::ALL, &[1e-4, 1e-7, 1e-10], 0.0);
    assert_eq!(rows.len(), 9);
    for m in Method::ALL {
        let r: Vec<_> = rows.iter().filter(|r| r.method == m).collect();
        assert!(r.iter().all(|x| x.failure.is_none()), "{m:?} failed");
        assert!(r[1].err_neck < r[0].err_neck.max(1e-9), "{m:?}: {} {}", r[0].err_neck, r[1].err_neck);
        assert!(r[1].err_neck < 1e-5 && r[1].err_shrinkage < 1e-5, "{m:?}");
        assert!(r[2].rhs > r[0].rhs);
    }
}

/// The full benchmark (`sinterdem bench pair` once wired): run with
/// `cargo test --release --test diffusion7_bench -- --ignored --nocapture`; writes to
/// `$SINTERDEM_BENCH_OUT` (default `target/bench-pair`).
#[test]
#[ignore]
fn bench_pair_full() {
    let out = std::env::var("SINTERDEM_BENCH_OUT").unwrap_or_else(|_| "target/bench-pair".into());
    let t = sinterdem::bench::diffusion7::bench_pair(std::path::Path::new(&out)).unwrap();
    println!("{t}");
}
