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
    let cells: Vec<usize> = position.iter().map(|x| lin(index_of(x))).collect();
    let (start, order) = bucket(&cells, ncell);
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

/// Counting sort of items by cell: `start[c]..start[c + 1]` indexes the items of cell `c` in
/// `order` (items of a cell in increasing index).
fn bucket(cells: &[usize], ncell: usize) -> (Vec<u32>, Vec<u32>) {
    let mut start = vec![0u32; ncell + 1];
    for &c in cells {
        start[c + 1] += 1;
    }
    for k in 0..ncell {
        start[k + 1] += start[k];
    }
    let mut fill = start.clone();
    let mut order = vec![0u32; cells.len()];
    for (i, &c) in cells.iter().enumerate() {
        order[fill[c] as usize] = i as u32;
        fill[c] += 1;
    }
    (start, order)
}

/// The minimum-image branch `d − L·round(d/L)` per axis (docs/packing.md (G1)) of a difference of
/// positions `d` [m] in the periodic box `l` [m].
#[inline]
pub fn minimum_image(d: Vector3<f64>, l: &Vector3<f64>) -> Vector3<f64> {
    Vector3::new(d.x - l.x * (d.x / l.x).round(), d.y - l.y * (d.y / l.y).round(), d.z - l.z * (d.z / l.z).round())
}

/// A touching pair of a periodic box: `i < j` and the image shift `s` (in box lengths) such that
/// `x_j + s·L − x_i` is the minimum-image branch vector.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PeriodicPair {
    pub i: u32,
    pub j: u32,
    pub shift: [i8; 3],
}

/// All pairs of a periodic box `[0, L)³` (positions wrapped into it first) with minimum-image
/// distance `< r_i + r_j + margin`. Each box length must exceed twice the largest reach
/// `2 r_max + margin`, so that at most one image of a partner touches (the caller checks). Sorted
/// by `i`, then pairs across no face before pairs across a face, then by `j` (the order a cell
/// list over the box plus its face images gives).
pub fn touching_pairs_periodic(position: &[Vector3<f64>], radius: &[f64], bbox: Vector3<f64>, margin: f64) -> Vec<PeriodicPair> {
    let n = position.len();
    if n < 2 {
        return Vec::new();
    }
    let r_max = radius.iter().copied().fold(0.0, f64::max);
    let cell = (2.0 * r_max + margin).max(f64::MIN_POSITIVE);
    let wrapped: Vec<Vector3<f64>> = position.iter().map(|x| Vector3::from_fn(|a, _| x[a].rem_euclid(bbox[a]))).collect();
    let cap = (64.0 * n as f64).cbrt().ceil().max(1.0);
    let dims: [usize; 3] = std::array::from_fn(|a| (bbox[a] / cell).floor().clamp(1.0, cap) as usize);
    let index_of = |x: &Vector3<f64>| -> [usize; 3] { std::array::from_fn(|a| ((x[a] / bbox[a] * dims[a] as f64) as usize).min(dims[a] - 1)) };
    let lin = |c: [usize; 3]| (c[2] * dims[1] + c[1]) * dims[0] + c[0];
    let ncell = dims[0] * dims[1] * dims[2];
    let cells: Vec<usize> = wrapped.iter().map(|x| lin(index_of(x))).collect();
    let (start, order) = bucket(&cells, ncell);
    // the distinct neighbour cells along one axis (fewer than three cells: each once)
    let around = |c: usize, m: usize| -> Vec<usize> {
        let mut v: Vec<usize> = [c + m - 1, c, c + 1].iter().map(|k| k % m).collect();
        v.sort_unstable();
        v.dedup();
        v
    };
    let pairs_of = |range: std::ops::Range<usize>| -> Vec<PeriodicPair> {
        let mut pairs = Vec::new();
        for i in range {
            let first = pairs.len();
            let (xi, ri) = (wrapped[i], radius[i]);
            let ci = index_of(&xi);
            for z in around(ci[2], dims[2]) {
                for y in around(ci[1], dims[1]) {
                    for x in around(ci[0], dims[0]) {
                        let c = lin([x, y, z]);
                        for &j in &order[start[c] as usize..start[c + 1] as usize] {
                            if j as usize <= i {
                                continue;
                            }
                            let d = wrapped[j as usize] - xi;
                            let shift: [i8; 3] = std::array::from_fn(|a| -(d[a] / bbox[a]).round() as i8);
                            let s = Vector3::from_fn(|a, _| shift[a] as f64 * bbox[a]);
                            let reach = ri + radius[j as usize] + margin;
                            if ((wrapped[j as usize] + s) - xi).norm_squared() < reach * reach {
                                pairs.push(PeriodicPair { i: i as u32, j, shift });
                            }
                        }
                    }
                }
            }
            pairs[first..].sort_unstable_by_key(|p| (p.shift != [0; 3], p.j));
        }
        pairs
    };
    const CHUNK: usize = 2048;
    if n < 4 * CHUNK {
        return pairs_of(0..n);
    }
    let parts: Vec<Vec<PeriodicPair>> = (0..n.div_ceil(CHUNK)).into_par_iter().map(|c| pairs_of(c * CHUNK..((c + 1) * CHUNK).min(n))).collect();
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

    #[test]
    fn periodic_search_equals_brute_force_over_images() {
        let mut s = 0x2545F4914F6CDD1Du64;
        for (n, spread, l) in [(300, 0.3, Vector3::new(8.0, 6.0, 5.0)), (2000, 0.1, Vector3::new(20.0, 20.0, 12.0)), (40, 0.0, Vector3::new(2.5, 3.0, 2.6))] {
            // positions partly outside the box: the search wraps them
            let pos: Vec<_> = (0..n).map(|_| Vector3::new(rng(&mut s) * 1.2 - 0.1, rng(&mut s), rng(&mut s) * 1.3).component_mul(&l)).collect();
            let rad: Vec<_> = (0..n).map(|_| 0.6 * (1.0 + spread * (2.0 * rng(&mut s) - 1.0))).collect();
            let margin = 0.02;
            let got = touching_pairs_periodic(&pos, &rad, l, margin);
            let mut want = Vec::new();
            for i in 0..n {
                for j in i + 1..n {
                    for sx in -2i8..=2 {
                        for sy in -2i8..=2 {
                            for sz in -2i8..=2 {
                                let sh = Vector3::new(sx as f64 * l.x, sy as f64 * l.y, sz as f64 * l.z);
                                let reach = rad[i] + rad[j] + margin;
                                if (pos[j] + sh - pos[i]).norm_squared() < reach * reach {
                                    want.push((i as u32, j as u32));
                                }
                            }
                        }
                    }
                }
            }
            let mut g: Vec<(u32, u32)> = got.iter().map(|p| (p.i, p.j)).collect();
            g.sort_unstable();
            assert_eq!(g, want, "n = {n}");
            assert!(got.iter().any(|p| p.shift != [0; 3]) && !got.is_empty());
            for p in &got {
                let (i, j) = (p.i as usize, p.j as usize);
                let w = |x: Vector3<f64>| Vector3::from_fn(|a, _| x[a].rem_euclid(l[a]));
                let b = w(pos[j]) + Vector3::from_fn(|a, _| p.shift[a] as f64 * l[a]) - w(pos[i]);
                assert!(b.norm() < rad[i] + rad[j] + margin);
            }
        }
    }
}
