//! Adaptive refinement of a grid sweep (`[refine]`, docs/SPEC.md §7).
//!
//! The finest resolution is the sweep's own grid. Level 0 computes a coarse
//! sub-grid: every axis at a common stride s (a power of two; the axis' last
//! value always included). Each *cell* of a level — a box whose corners are
//! neighbouring points of that level's sub-grid — is refined when its
//! corners disagree on the refined column (differ as text, or by more than
//! `threshold` for a continuous column): the next level computes every
//! point of the sub-grid at stride s/2 inside the box (its edges' midpoints,
//! its faces' and its centre), and looks at the box's 2^d sub-cells. Cells
//! whose corners agree are not looked into again. The last level has stride
//! 1: the full resolution. It works for any number of axes (an axis with
//! one value takes no part).
//!
//! A point that was not computed takes the value of its nearest computed
//! point (Euclidean distance in grid steps; [`nearest`]): what `cradle plot`
//! and `cradle fill` draw and write. An island smaller than the coarse cells
//! (whose corners all lie outside it) is missed.

use std::collections::{BTreeSet, HashMap};

use serde::Serialize;

use crate::output::row::Cell;

mod run;
pub use run::run;

/// The `[refine]` table.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RefineSpec {
    /// The column the diagram is about.
    pub column: String,
    /// For a continuous column: corners differing by more than this differ.
    pub threshold: Option<f64>,
    /// The coarse level's spacing in grid steps (a power of two).
    pub stride: u64,
}

/// The default coarse stride for axes of `dims` values: the largest power
/// of two that leaves at least 16 coarse steps on the longest axis (32 for a
/// 1000-value axis), at least 1.
pub fn default_stride(dims: &[u64]) -> u64 {
    let longest = dims.iter().copied().max().unwrap_or(1).saturating_sub(1);
    let mut s = 1u64;
    while longest / (2 * s) >= 16 {
        s *= 2;
    }
    s
}

/// Whether the corner values `vals` disagree: as values (categories,
/// counts, statuses), or (with a threshold) as numbers differing by more
/// than it; a missing or non-finite number beside a finite one disagrees.
pub fn disagree(vals: &[Cell], threshold: Option<f64>) -> bool {
    match threshold {
        None => vals.iter().any(|v| *v != vals[0]),
        Some(t) => {
            let nums: Vec<Option<f64>> = vals
                .iter()
                .map(|v| match v {
                    Cell::Num(x) => Some(*x),
                    Cell::Int(x) => Some(*x as f64),
                    Cell::Text(_) | Cell::Null => None,
                })
                .map(|x| x.filter(|x| x.is_finite()))
                .collect();
            if nums.iter().all(Option::is_none) {
                return false;
            }
            if nums.iter().any(Option::is_none) {
                return true;
            }
            let (lo, hi) = nums
                .iter()
                .flatten()
                .fold((f64::MAX, f64::MIN), |(a, b), &x| (a.min(x), b.max(x)));
            hi - lo > t
        }
    }
}

/// A box of the grid: the first and last index on every axis.
type GridBox = Vec<(u64, u64)>;

/// The level-by-level plan of a refinement over a grid of `dims` values per
/// axis (first axis slowest, as scene ids are).
pub struct Refiner {
    dims: Vec<u64>,
    /// Id step of each axis.
    steps: Vec<u64>,
    /// Half the current stride: where the next level splits.
    stride: u64,
    /// The current level's cells (to be checked once its points are known).
    cells: Vec<GridBox>,
    /// Every point computed so far.
    pub computed: BTreeSet<u64>,
    /// The part of the first axis refined: [first, last] index.
    range0: (u64, u64),
}

/// The sub-grid indices of one axis of `n` values at `stride`.
fn lattice(n: u64, stride: u64) -> Vec<u64> {
    let mut v: Vec<u64> = (0..n).step_by(stride as usize).collect();
    if *v.last().unwrap_or(&0) != n - 1 {
        v.push(n - 1);
    }
    v
}

/// The intervals between neighbouring `points` of one axis (one point:
/// the degenerate interval of an axis that takes no part).
fn intervals(points: &[u64]) -> Vec<(u64, u64)> {
    if points.len() == 1 {
        vec![(points[0], points[0])]
    } else {
        points.windows(2).map(|w| (w[0], w[1])).collect()
    }
}

/// Every combination of one choice per axis (first axis slowest).
fn product<T: Clone>(choices: &[Vec<T>]) -> Vec<Vec<T>> {
    let mut out: Vec<Vec<T>> = vec![vec![]];
    for c in choices {
        out = out
            .into_iter()
            .flat_map(|p| {
                c.iter().map(move |x| {
                    let mut q = p.clone();
                    q.push(x.clone());
                    q
                })
            })
            .collect();
    }
    out
}

impl Refiner {
    /// The refinement of a grid of `dims` values per axis from `stride`.
    pub fn new(dims: &[u64], stride: u64) -> Refiner {
        let mut steps = vec![1u64; dims.len()];
        for k in (0..dims.len().saturating_sub(1)).rev() {
            steps[k] = steps[k + 1] * dims[k + 1];
        }
        Refiner {
            dims: dims.to_vec(),
            steps,
            stride,
            cells: vec![],
            computed: BTreeSet::new(),
            range0: (0, dims.first().map_or(0, |n| n - 1)),
        }
    }

    /// A refinement of the slab of the grid whose first-axis index lies in
    /// `[first, last]` (both on the coarse lattice: a shard's part).
    pub fn with_range(dims: &[u64], stride: u64, (first, last): (u64, u64)) -> Refiner {
        let mut r = Refiner::new(dims, stride);
        r.range0 = (first, last);
        r
    }

    /// The coarse lattice of the first axis.
    pub fn coarse_first_axis(dims: &[u64], stride: u64) -> Vec<u64> {
        lattice(dims[0], stride)
    }

    fn id(&self, idx: &[u64]) -> u64 {
        idx.iter().zip(&self.steps).map(|(i, s)| i * s).sum()
    }

    /// Grid indices of scene `id`.
    pub fn indices(&self, mut id: u64) -> Vec<u64> {
        self.steps
            .iter()
            .map(|s| {
                let i = id / s;
                id %= s;
                i
            })
            .collect()
    }

    /// The coarse level: its scene ids, ascending.
    pub fn start(&mut self) -> Vec<u64> {
        let mut lat: Vec<Vec<u64>> = self.dims.iter().map(|&n| lattice(n, self.stride)).collect();
        let (first, last) = self.range0;
        lat[0].retain(|&i| (first..=last).contains(&i));
        let intervals: Vec<Vec<(u64, u64)>> = lat.iter().map(|l| intervals(l)).collect();
        self.cells = product(&intervals);
        let ids: Vec<u64> = product(&lat).iter().map(|p| self.id(p)).collect();
        self.computed.extend(&ids);
        ids
    }

    /// The current stride (the spacing of the level just planned).
    pub fn stride(&self) -> u64 {
        self.stride
    }

    /// After a level's points are known (`value` of any computed id): the
    /// next level's new scene ids, ascending, or `None` when done.
    pub fn next(
        &mut self,
        value: &dyn Fn(u64) -> Cell,
        threshold: Option<f64>,
    ) -> Option<Vec<u64>> {
        if self.stride <= 1 {
            return None;
        }
        let half = self.stride / 2;
        let mut new_ids = BTreeSet::new();
        let mut next_cells = vec![];
        for cell in std::mem::take(&mut self.cells) {
            let corners: Vec<u64> = product(
                &cell
                    .iter()
                    .map(|&(a, b)| if a == b { vec![a] } else { vec![a, b] })
                    .collect::<Vec<_>>(),
            )
            .iter()
            .map(|p| self.id(p))
            .collect();
            let vals: Vec<Cell> = corners.iter().map(|&c| value(c)).collect();
            if !disagree(&vals, threshold) {
                continue;
            }
            // Split points and sub-intervals of each axis.
            let splits: Vec<Vec<u64>> = cell
                .iter()
                .map(|&(a, b)| {
                    if a + half < b {
                        vec![a, a + half, b]
                    } else if a == b {
                        vec![a]
                    } else {
                        vec![a, b]
                    }
                })
                .collect();
            for p in product(&splits) {
                let id = self.id(&p);
                if !self.computed.contains(&id) {
                    new_ids.insert(id);
                }
            }
            let subs: Vec<Vec<(u64, u64)>> = splits.iter().map(|s| intervals(s)).collect();
            // Sub-cells with room for another level (an interval ≥ 2 steps).
            next_cells.extend(
                product(&subs)
                    .into_iter()
                    .filter(|c| c.iter().any(|&(a, b)| b - a >= 2)),
            );
        }
        self.stride = half;
        self.cells = next_cells;
        self.computed.extend(&new_ids);
        Some(new_ids.into_iter().collect())
    }
}

/// For every point of a grid of `dims` values per axis, the nearest of the
/// `sites` (scene ids; Euclidean distance in grid steps): an exact distance
/// transform, one axis at a time (Felzenszwalb & Huttenlocher's lower
/// envelope of parabolas), carrying the nearest site. Equidistant sites:
/// the one the envelope keeps (deterministic). Returns `u64::MAX` where
/// there is no site at all.
pub fn nearest(dims: &[u64], sites: &[u64]) -> Vec<u64> {
    let total: u64 = dims.iter().product();
    let mut dist = vec![f64::INFINITY; total as usize];
    let mut site = vec![u64::MAX; total as usize];
    for &s in sites {
        dist[s as usize] = 0.0;
        site[s as usize] = s;
    }
    let mut steps = vec![1u64; dims.len()];
    for k in (0..dims.len().saturating_sub(1)).rev() {
        steps[k] = steps[k + 1] * dims[k + 1];
    }
    for (k, &n) in dims.iter().enumerate() {
        let n = n as usize;
        if n <= 1 {
            continue;
        }
        let step = steps[k] as usize;
        let (mut f, mut fs) = (vec![0.0; n], vec![0u64; n]);
        let (mut v, mut z) = (vec![0usize; n], vec![0.0f64; n + 1]);
        // Every line along axis k: its start is an index with 0 on axis k.
        for start in 0..total as usize {
            if !(start / step).is_multiple_of(n) {
                continue;
            }
            for i in 0..n {
                f[i] = dist[start + i * step];
                fs[i] = site[start + i * step];
            }
            // Lower envelope of the parabolas (q − i)² + f(i), finite f only.
            let mut len = 0usize;
            for q in 0..n {
                if !f[q].is_finite() {
                    continue;
                }
                loop {
                    if len == 0 {
                        v[0] = q;
                        z[0] = f64::NEG_INFINITY;
                        z[1] = f64::INFINITY;
                        len = 1;
                        break;
                    }
                    let p = v[len - 1];
                    let s = ((f[q] + (q * q) as f64) - (f[p] + (p * p) as f64))
                        / (2.0 * (q as f64 - p as f64));
                    if s <= z[len - 1] {
                        len -= 1;
                        continue;
                    }
                    v[len] = q;
                    z[len] = s;
                    z[len + 1] = f64::INFINITY;
                    len += 1;
                    break;
                }
            }
            if len == 0 {
                continue;
            }
            let mut j = 0;
            for q in 0..n {
                while z[j + 1] < q as f64 {
                    j += 1;
                }
                let p = v[j];
                let d = (q as f64 - p as f64).powi(2) + f[p];
                dist[start + q * step] = d;
                site[start + q * step] = fs[p];
            }
        }
    }
    site
}

/// The values of the refined column computed so far, by scene id, typed
/// as the table types the column.
pub type Values = HashMap<u64, Cell>;

#[cfg(test)]
mod tests {
    use super::*;

    /// Refinement of a known map: points inside a disc are "1".
    #[test]
    fn a_disc_is_found_and_filled_exactly_with_few_points() {
        let dims = [257u64, 300];
        let inside = |id: u64| {
            let (i, j) = ((id / 300) as f64, (id % 300) as f64);
            ((i - 120.0).powi(2) + (j - 140.0).powi(2) < 70.0f64.powi(2)) as u8
        };
        let mut r = Refiner::new(&dims, default_stride(&dims));
        assert_eq!(r.stride(), 16);
        let mut level = r.start();
        let mut vals: Values = HashMap::new();
        loop {
            for &id in &level {
                assert!(
                    vals.insert(id, Cell::Int(inside(id) as u64)).is_none(),
                    "computed twice"
                );
            }
            match r.next(&|id| vals[&id].clone(), None) {
                Some(l) => level = l,
                None => break,
            }
        }
        let sites: Vec<u64> = vals.keys().copied().collect();
        let near = nearest(&dims, &sites);
        let wrong = (0..257 * 300)
            .filter(|&id| vals[&near[id as usize]] != Cell::Int(inside(id) as u64))
            .count();
        assert!(wrong <= 3, "{wrong} cells wrong");
        assert!(sites.len() < 257 * 300 / 8, "{} computed", sites.len());
        // The coarse level holds both ends of every axis.
        for id in [0, 299, 256 * 300, 257 * 300 - 1] {
            assert!(vals.contains_key(&id));
        }
    }

    #[test]
    fn nearest_site_is_the_closest_by_brute_force() {
        let dims = [13u64, 7, 5];
        let sites = [0u64, 17, 100, 333, 454];
        let near = nearest(&dims, &sites);
        let idx = |id: u64| [(id / 35) as f64, ((id / 5) % 7) as f64, (id % 5) as f64];
        let d2 = |a: u64, b: u64| {
            let (x, y) = (idx(a), idx(b));
            (0..3).map(|k| (x[k] - y[k]).powi(2)).sum::<f64>()
        };
        for id in 0..13 * 7 * 5 {
            let best = sites.iter().map(|&s| d2(id, s)).fold(f64::MAX, f64::min);
            assert_eq!(d2(id, near[id as usize]), best, "id {id}");
        }
    }

    #[test]
    fn disagreement_by_value_or_threshold() {
        use Cell::{Int, Null, Num, Text};
        let text = |t: &str| Text(t.to_string());
        assert!(!disagree(&[Int(1), Int(1), Int(1)], None));
        assert!(disagree(&[Int(1), Int(2)], None));
        assert!(disagree(&[text("ok"), text("step_cap")], None));
        assert!(!disagree(&[Num(0.5), Num(0.52)], Some(0.05)));
        assert!(disagree(&[Num(0.5), Num(0.6)], Some(0.05)));
        assert!(disagree(&[Num(0.5), Null], Some(0.05)));
        assert!(disagree(&[Num(0.5), Num(f64::NAN)], Some(0.05)));
        assert!(!disagree(&[Null, Null], Some(0.05)));
        assert!(disagree(&[Int(3), Int(5)], Some(1.0)));
        // A row read back from CSV text types as the row it was written from.
        use crate::output::row::ColType;
        assert_eq!(Cell::parse("0.52", ColType::Num), Num(0.52));
        assert_eq!(Cell::parse("", ColType::Num), Null);
        assert_eq!(Cell::parse("7", ColType::Int), Int(7));
        assert_eq!(Cell::parse("ok", ColType::Status), text("ok"));
    }
}
