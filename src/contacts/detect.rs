//! Neighbour search: a uniform cell list giving all pairs of spheres whose gap is below a margin,
//! in O(N) for packings of bounded size ratio (docs/design.md, "The loop", stage 1).
//!
//! The cell edge is the largest sphere diameter plus the margin, so any touching pair lies in the
//! same or adjacent cells. Cells are sorted (counting sort by linear cell index), so the result
//! is deterministic and independent of thread count; large searches run on rayon by fixed chunks
//! of particles.

use nalgebra::Vector3;
use rayon::prelude::*;

/// All pairs `(i, j)`, `i < j`, with `|x_i − x_j| < r_i + r_j + margin`, sorted lexicographically.
/// `margin` [m] ≥ 0 lets a caller find pairs that are about to touch.
pub fn touching_pairs(position: &[Vector3<f64>], radius: &[f64], margin: f64) -> Vec<(u32, u32)> {
    let n = position.len();
    if n < 2 {
        return Vec::new();
    }
    let r_max = radius.iter().copied().fold(0.0, f64::max);
    let cell = (2.0 * r_max + margin).max(f64::MIN_POSITIVE);
    let mut lo = Vector3::repeat(f64::INFINITY);
    let mut hi = Vector3::repeat(f64::NEG_INFINITY);
    for x in position {
        lo = lo.inf(x);
        hi = hi.sup(x);
    }
    // Cells per axis: floor(extent / cell) so that every cell edge is at least `cell`, capped so
    // that the grid never has more than ~64 N cells (sparse clouds).
    let cap = (64.0 * n as f64).cbrt().ceil();
    let mut dims = [1usize; 3];
    let mut size = [f64::INFINITY; 3];
    for a in 0..3 {
        let ext = hi[a] - lo[a];
        let m = (ext / cell).floor().clamp(1.0, cap);
        dims[a] = m as usize;
        if m > 1.0 {
            size[a] = ext / m;
        }
    }
    let index_of = |x: &Vector3<f64>| -> [usize; 3] {
        let mut c = [0usize; 3];
        for a in 0..3 {
            c[a] = if size[a].is_finite() { (((x[a] - lo[a]) / size[a]) as usize).min(dims[a] - 1) } else { 0 };
        }
        c
    };
    let ncell = dims[0] * dims[1] * dims[2];
    let lin = |c: [usize; 3]| (c[2] * dims[1] + c[1]) * dims[0] + c[0];
    // counting sort of particles by cell
    let mut start = vec![0u32; ncell + 1];
    let cells: Vec<usize> = position.iter().map(|x| lin(index_of(x))).collect();
    for &c in &cells {
        start[c + 1] += 1;
    }
    for k in 0..ncell {
        start[k + 1] += start[k];
    }
    let mut fill = start.clone();
    let mut order = vec![0u32; n];
    for (i, &c) in cells.iter().enumerate() {
        order[fill[c] as usize] = i as u32;
        fill[c] += 1;
    }
    // positions and radii in cell order: the inner loop reads contiguous memory
    let sorted: Vec<(Vector3<f64>, f64)> = order.iter().map(|&j| (position[j as usize], radius[j as usize])).collect();
    // pairs of particle i in cells around its own, j > i, sorted by j: concatenated in order of i
    // they form the sorted list. Fixed chunks of i, so the result is the same in parallel.
    let pairs_of = |range: std::ops::Range<usize>| -> Vec<(u32, u32)> {
        let mut pairs = Vec::new();
        for i in range {
            let first = pairs.len();
            let (xi, ri) = (position[i], radius[i]);
            let ci = index_of(&xi);
            // the three cells of a row along x are contiguous in the cell order: 9 runs
            let (x0, x1) = (ci[0].saturating_sub(1), (ci[0] + 1).min(dims[0] - 1));
            for z in ci[2].saturating_sub(1)..=(ci[2] + 1).min(dims[2] - 1) {
                for y in ci[1].saturating_sub(1)..=(ci[1] + 1).min(dims[1] - 1) {
                    let (s0, s1) = (start[lin([x0, y, z])] as usize, start[lin([x1, y, z]) + 1] as usize);
                    for (&j, (xj, rj)) in order[s0..s1].iter().zip(&sorted[s0..s1]) {
                        if j as usize <= i {
                            continue;
                        }
                        let reach = ri + rj + margin;
                        if (xi - xj).norm_squared() < reach * reach {
                            pairs.push((i as u32, j));
                        }
                    }
                }
            }
            pairs[first..].sort_unstable();
        }
        pairs
    };
    const CHUNK: usize = 2048;
    if n < 4 * CHUNK {
        return pairs_of(0..n);
    }
    let parts: Vec<Vec<(u32, u32)>> = (0..n.div_ceil(CHUNK)).into_par_iter().map(|c| pairs_of(c * CHUNK..((c + 1) * CHUNK).min(n))).collect();
    parts.concat()
}

/// Brute-force O(N²) reference for [`touching_pairs`] (tests and debugging).
pub fn touching_pairs_brute(position: &[Vector3<f64>], radius: &[f64], margin: f64) -> Vec<(u32, u32)> {
    let mut pairs = Vec::new();
    for i in 0..position.len() {
        for j in i + 1..position.len() {
            let reach = radius[i] + radius[j] + margin;
            if (position[i] - position[j]).norm_squared() < reach * reach {
                pairs.push((i as u32, j as u32));
            }
        }
    }
    pairs
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small deterministic generator (xorshift) so the test needs no extra crate.
    fn rng(seed: &mut u64) -> f64 {
        *seed ^= *seed << 13;
        *seed ^= *seed >> 7;
        *seed ^= *seed << 17;
        (*seed >> 11) as f64 / (1u64 << 53) as f64
    }

    #[test]
    fn cell_list_equals_brute_force_on_random_packings() {
        let mut s = 0x9E3779B97F4A7C15u64;
        for (n, spread, box_len) in [(200, 0.5, 10.0), (1000, 0.1, 20.0), (50, 0.9, 3.0), (400, 0.0, 1e-3)] {
            let base = if box_len < 1.0 { 5e-5 } else { 0.6 };
            let pos: Vec<_> = (0..n).map(|_| Vector3::new(rng(&mut s), rng(&mut s), rng(&mut s) * 0.3) * box_len).collect();
            let rad: Vec<_> = (0..n).map(|_| base * (1.0 + spread * (2.0 * rng(&mut s) - 1.0))).collect();
            for margin in [0.0, 0.05 * base] {
                let a = touching_pairs(&pos, &rad, margin);
                let b = touching_pairs_brute(&pos, &rad, margin);
                assert_eq!(a, b, "n = {n}");
                if margin == 0.0 && box_len > 1.0 {
                    assert!(!a.is_empty());
                }
            }
        }
    }

    #[test]
    fn degenerate_inputs() {
        assert!(touching_pairs(&[], &[], 0.0).is_empty());
        let p = vec![Vector3::zeros(); 3];
        assert_eq!(touching_pairs(&p, &[1.0; 3], 0.0), vec![(0, 1), (0, 2), (1, 2)]);
    }
}
