//! Uniform cubic cell grids with counting-sort (CSR) storage: the broad-phase cell list, the
//! static body-frame marker bins of each body, and the per-pair world-frame bins of the
//! narrow phase. All storage lives in caller-owned `Vec`s that are cleared and refilled, so
//! that a warm grid rebuild does not allocate.

use crate::rigid::Vec3;

/// The geometry of a grid: origin (lower corner), cell edge and cell counts.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Geometry {
    pub origin: Vec3,
    pub edge: f64,
    pub dims: [usize; 3],
}

impl Geometry {
    /// A grid over the box `[lo, hi]` with cells of edge at least `edge`, grown (by factors of
    /// 1.5) until there are at most `max_cells` cells.
    pub fn covering(lo: &Vec3, hi: &Vec3, edge: f64, max_cells: usize) -> Self {
        let mut edge = edge;
        loop {
            let dims = [0, 1, 2].map(|a| {
                let n = ((hi[a] - lo[a]) / edge).floor();
                // Saturating: positions blown up by an instability (≥ 1e19 cells) must not wrap
                // to 0 cells; the edge then grows until the grid fits.
                if n.is_finite() && n >= 0.0 {
                    (n as usize).saturating_add(1)
                } else {
                    1
                }
            });
            if dims[0].saturating_mul(dims[1]).saturating_mul(dims[2]) <= max_cells.max(1) {
                return Self { origin: *lo, edge, dims };
            }
            edge *= 1.5;
        }
    }

    /// Number of cells.
    pub fn len(&self) -> usize {
        self.dims[0] * self.dims[1] * self.dims[2]
    }

    /// Integer cell coordinates of `x` (unclamped; may lie outside the grid).
    #[inline(always)]
    pub fn coords(&self, x: &Vec3) -> [i64; 3] {
        [0, 1, 2].map(|a| ((x[a] - self.origin[a]) / self.edge).floor() as i64)
    }

    /// Linear index of in-range coordinates.
    #[inline(always)]
    pub fn index(&self, c: [usize; 3]) -> usize {
        (c[2] * self.dims[1] + c[1]) * self.dims[0] + c[0]
    }

    /// The cell of `x`, clamped into the grid.
    #[inline(always)]
    pub fn clamped_index(&self, x: &Vec3) -> usize {
        let c = self.coords(x);
        self.index([0, 1, 2].map(|a| c[a].clamp(0, self.dims[a] as i64 - 1) as usize))
    }

    /// The inclusive coordinate range `[lo, hi]` per axis of the cells that meet the box
    /// `[c − r, c + r]`, clipped to the grid; `None` if it misses the grid.
    #[inline(always)]
    pub fn range(&self, c: &Vec3, r: f64) -> Option<[[usize; 2]; 3]> {
        let mut out = [[0usize; 2]; 3];
        for a in 0..3 {
            let lo = ((c[a] - r - self.origin[a]) / self.edge).floor() as i64;
            let hi = ((c[a] + r - self.origin[a]) / self.edge).floor() as i64;
            let top = self.dims[a] as i64 - 1;
            if hi < 0 || lo > top {
                return None;
            }
            out[a] = [lo.max(0) as usize, hi.min(top) as usize];
        }
        Some(out)
    }

    /// The inclusive range of the 3 × 3 × 3 block around integer coordinates `c`, clipped.
    #[inline(always)]
    pub fn neighbours(&self, c: [i64; 3]) -> Option<[[usize; 2]; 3]> {
        let mut out = [[0usize; 2]; 3];
        for a in 0..3 {
            let top = self.dims[a] as i64 - 1;
            let (lo, hi) = (c[a] - 1, c[a] + 1);
            if hi < 0 || lo > top {
                return None;
            }
            out[a] = [lo.max(0) as usize, hi.min(top) as usize];
        }
        Some(out)
    }
}

/// Counting sort of `n` items into the cells `cell(k)`: afterwards the items of cell `c` are
/// `items[start[c]..start[c + 1]]`, in increasing `k`. No allocation once the vectors have
/// grown to size.
pub(crate) fn fill(
    cells: usize,
    n: usize,
    cell: impl Fn(usize) -> usize,
    cell_of: &mut Vec<u32>,
    start: &mut Vec<u32>,
    items: &mut Vec<u32>,
) {
    cell_of.clear();
    start.clear();
    start.resize(cells + 1, 0);
    for k in 0..n {
        let c = cell(k);
        cell_of.push(c as u32);
        start[c] += 1;
    }
    // Inclusive prefix sums: start[c] = end of cell c.
    for c in 1..cells {
        start[c] += start[c - 1];
    }
    start[cells] = n as u32;
    items.clear();
    items.resize(n, 0);
    for k in (0..n).rev() {
        let c = cell_of[k] as usize;
        start[c] -= 1;
        items[start[c] as usize] = k as u32;
    }
}

/// Visits the cells of the inclusive coordinate range `r` (x fastest).
#[inline(always)]
pub(crate) fn for_cells(g: &Geometry, r: [[usize; 2]; 3], mut f: impl FnMut(usize)) {
    for z in r[2][0]..=r[2][1] {
        for y in r[1][0]..=r[1][1] {
            for x in r[0][0]..=r[0][1] {
                f(g.index([x, y, z]));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counting_sort_is_stable_and_complete() {
        let cells = [3usize, 0, 3, 1, 0, 3];
        let (mut co, mut st, mut it) = (Vec::new(), Vec::new(), Vec::new());
        fill(4, cells.len(), |k| cells[k], &mut co, &mut st, &mut it);
        assert_eq!(st, vec![0, 2, 3, 3, 6]);
        assert_eq!(it, vec![1, 4, 3, 0, 2, 5]);
    }

    #[test]
    fn covering_grid_is_capped() {
        let g = Geometry::covering(&Vec3::zeros(), &Vec3::repeat(100.0), 1.0, 1000);
        assert!(g.len() <= 1000 && g.edge >= 1.0);
        let c = g.coords(&Vec3::repeat(100.0));
        assert!((0..3).all(|a| (c[a] as usize) < g.dims[a]));
        assert!(g.range(&Vec3::repeat(-5.0), 1.0).is_none());
        assert_eq!(g.range(&Vec3::repeat(-5.0), 6.0).unwrap()[0][0], 0);
    }
}
