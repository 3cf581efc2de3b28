//! A bonded test packing for the mechanics' tests and `sinterdem bench mechanics`: an FCC
//! lattice with nearest-neighbour distance 2R (R = 50 µm), radii R·(1 ± 5 %) uniform (a seeded
//! xorshift), bonds between the overlapping neighbours (about half of them: mean coordination ≈ 6,
//! an irregular graph with some rattlers and floating clusters).

use nalgebra::Vector3;

/// The next uniform number in [0, 1) of a xorshift64 stream (`seed` is the state).
pub fn rng(seed: &mut u64) -> f64 {
    *seed ^= *seed << 13;
    *seed ^= *seed >> 7;
    *seed ^= *seed << 17;
    (*seed >> 11) as f64 / (1u64 << 53) as f64
}

/// A bonded packing of about `n` particles (see the module doc): positions [m], radii [m],
/// bonds, and `[y4, y7]` per bond from the two-sphere overlap (I1) [m].
pub fn fcc_packing(n: usize, seed: u64) -> (Vec<Vector3<f64>>, Vec<f64>, Vec<[u32; 2]>, Vec<[f64; 2]>) {
    let r0 = 50e-6;
    let a = 2.0 * r0 * std::f64::consts::SQRT_2;
    let m = ((n as f64 / 4.0).cbrt().round() as usize).max(1);
    let basis = [[0.0, 0.0, 0.0], [0.5, 0.5, 0.0], [0.5, 0.0, 0.5], [0.0, 0.5, 0.5]];
    let mut s = seed.max(1);
    let (mut pos, mut rad) = (Vec::new(), Vec::new());
    for i in 0..m {
        for j in 0..m {
            for k in 0..m {
                for bvec in &basis {
                    pos.push(Vector3::new(i as f64 + bvec[0], j as f64 + bvec[1], k as f64 + bvec[2]) * a + Vector3::repeat(r0));
                    rad.push(r0 * (1.0 + 0.05 * (2.0 * rng(&mut s) - 1.0)));
                }
            }
        }
    }
    let pairs: Vec<[u32; 2]> = crate::contacts::detect::touching_pairs(&pos, &rad, 0.0).into_iter().map(|(i, j)| [i, j]).collect();
    let y = pairs
        .iter()
        .map(|&[i, j]| {
            let (ra, rb) = (rad[i as usize], rad[j as usize]);
            let d = (pos[j as usize] - pos[i as usize]).norm();
            [(d * d + ra * ra - rb * rb) / (2.0 * d), (d * d + rb * rb - ra * ra) / (2.0 * d)]
        })
        .collect();
    (pos, rad, pairs, y)
}
