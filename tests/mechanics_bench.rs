//! The mechanics benchmark as an ignored test until `sinterdem bench mechanics` is wired:
//! `MECH_BENCH_SIZES=1000,10000,100000 cargo test --release --test mechanics_bench -- --ignored --nocapture`.
//! The non-ignored test runs the bench code on a tiny packing so it cannot rot.

use sinterdem::bench::mechanics::bench_mechanics;

#[test]
#[ignore]
fn bench_mechanics_table() {
    let sizes: Vec<usize> =
        std::env::var("MECH_BENCH_SIZES").unwrap_or_else(|_| "1000,10000".into()).split(',').filter_map(|s| s.trim().parse().ok()).collect();
    println!("{}", bench_mechanics(&sizes).unwrap());
}

#[test]
fn bench_runs_on_a_small_packing() {
    let t = bench_mechanics(&[200]).unwrap();
    assert!(t.lines().count() >= 5, "{t}");
}
