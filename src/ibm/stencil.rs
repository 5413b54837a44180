//! The stencil of each marker: the nodes within the kernel's support and their weights,
//! computed once per marker per step into reusable buffers, and the z-slab schedule that makes
//! spreading parallel and deterministic ([`super::transfer`]).
//!
//! # Geometry
//! Node `(i, j, k)` of the [`Grid`] sits at world position `(i, j, k)` (lattice units). A marker
//! at `X` gets, per axis, the `W = kernel.width()` consecutive nodes
//! `j = ⌊X − h⌋ + 1, …, ⌊X − h⌋ + W` (`h = kernel.support()`; every node with `|X − j| < h` is
//! among them) with 1-D weights `φ(X − j)`. The 3-D weight of node `(i, j, k)` is the product
//! `δ = (φ_z · φ_y) · φ_x`, always evaluated in this order, so interpolation and spreading use
//! bit-identical weights.
//!
//! Storage is the tensor-product form, struct of arrays over markers: per marker and axis the
//! (up to 4) node coordinates, their 1-D weights and their count — about 155 bytes per marker
//! with the slab keys, instead of 64 × 12 for the expanded 3-D list. [`Stencils::build`] refills the buffers in place; once
//! their capacities cover the marker count (and the grid's slab count) it allocates nothing.
//!
//! # Periodic axes
//! Node coordinates wrap modulo `n`; the marker may sit anywhere (its position is not wrapped,
//! only its nodes). On an axis shorter than the stencil (e.g. a 1-node periodic axis) several
//! stencil points land on the same node and their weights add up: still a partition of unity.
//!
//! # Walled axes: dropped nodes, renormalised weights
//! With half-way bounce-back the box spans `[−½, n − ½]` on a walled axis; a marker must lie in
//! it ([`StencilError::OutsideBox`] otherwise: no silent clamping). Stencil points outside
//! `[0, n)` are dropped, and if the dropped 1-D weights were non-zero the kept ones are divided
//! by their sum. Because `δ` is a product, renormalising each axis renormalises the 3-D weights:
//! after it `Σ δ = 1` again (to round-off), so
//! - a uniform velocity still interpolates exactly (the direct-forcing estimate is not damped
//!   next to a wall), and
//! - spreading still conserves the total force: the fluid receives exactly minus what the
//!   markers' bodies receive (Newton's third law between fluid and particles). Without the
//!   renormalisation the dropped fraction — up to 1/6 per axis for [`DeltaKernel::Roma3`] at
//!   `X = 0` — would vanish into the wall.
//!
//! The cost: next to a wall the first moment is no longer zero (interpolation is first- rather
//! than second-order accurate there, and the spread force's centroid moves up to a fraction of
//! a spacing away from the wall). Adjointness is unaffected: it needs only that interpolation
//! and spreading use the same weights, whatever they are, and both read them from here.

use rayon::prelude::*;

use super::kernel::{DeltaKernel, MAX_WIDTH};
use crate::lattice::{Grid, NodeLayout};

/// A marker that cannot be given a stencil.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum StencilError {
    /// A coordinate is NaN or infinite.
    #[error("marker {marker}: position {position:?} is not finite")]
    NonFinite {
        /// Index of the marker.
        marker: usize,
        /// Its position.
        position: [f64; 3],
    },
    /// On a walled axis, the marker lies outside the box `[−½, n − ½]`.
    #[error(
        "marker {marker}: position {position:?} lies outside the box on walled axis {axis} \
         (allowed: -0.5 <= x <= {max})"
    )]
    OutsideBox {
        /// Index of the marker.
        marker: usize,
        /// Its position.
        position: [f64; 3],
        /// 0 = x, 1 = y, 2 = z.
        axis: usize,
        /// The upper end of the box on that axis, `n − ½`.
        max: f64,
    },
}

/// Node coordinates of one marker's stencil: `[axis][point]`.
type Nodes = [[u32; MAX_WIDTH]; 3];
/// 1-D weights of one marker's stencil: `[axis][point]`.
type Weights = [[f64; MAX_WIDTH]; 3];

/// The stencils of a set of markers (nodes and weights), and the slab schedule for spreading.
///
/// Reused across steps: [`Stencils::build`] overwrites everything, allocation-free once the
/// buffers are large enough.
#[derive(Clone, Debug)]
pub struct Stencils {
    kernel: DeltaKernel,
    grid: Grid,
    periodic: [bool; 3],
    /// Per marker: node coordinate per axis and point (only the first `len[a]` are used).
    node: Vec<Nodes>,
    /// Per marker: 1-D weight per axis and point.
    weight: Vec<Weights>,
    /// Per marker: number of points per axis.
    len: Vec<[u8; 3]>,
    /// Per marker: its z-slab (filled by `build`, consumed by the counting sort).
    slab: Vec<u32>,
    /// z-planes per slab (the last slab is thicker): `kernel.width()`.
    slab_thickness: usize,
    /// Number of slabs; 1 means spreading runs serially.
    slabs: usize,
    /// `order[slab_start[s]..slab_start[s + 1]]` are the markers of slab `s`, in input order.
    slab_start: Vec<u32>,
    /// Marker indices grouped by slab.
    order: Vec<u32>,
}

/// Fewest slabs for which spreading runs in parallel (each phase then has ≥ 2 slabs).
pub const MIN_PARALLEL_SLABS: usize = 4;

/// Markers per task of [`Stencils::build`]: large enough that rayon's per-task cost
/// vanishes, small enough for two threads to share 10⁴ markers evenly.
const BUILD_CHUNK: usize = 512;

impl Stencils {
    /// Empty stencils for the given kernel (no markers, a 0-node grid).
    pub fn new(kernel: DeltaKernel) -> Self {
        Self {
            kernel,
            grid: Grid::new(0, 0, 0),
            periodic: [true; 3],
            node: Vec::new(),
            weight: Vec::new(),
            len: Vec::new(),
            slab: Vec::new(),
            slab_thickness: kernel.width(),
            slabs: 1,
            slab_start: Vec::new(),
            order: Vec::new(),
        }
    }

    /// The kernel.
    pub fn kernel(&self) -> DeltaKernel {
        self.kernel
    }

    /// The grid of the last [`Stencils::build`].
    pub fn grid(&self) -> Grid {
        self.grid
    }

    /// Periodicity per axis of the last [`Stencils::build`].
    pub fn periodic(&self) -> [bool; 3] {
        self.periodic
    }

    /// Number of markers.
    pub fn len(&self) -> usize {
        self.node.len()
    }

    /// Whether there are no markers.
    pub fn is_empty(&self) -> bool {
        self.node.is_empty()
    }

    /// Number of z-slabs of the spreading schedule (1: spreading runs serially; see
    /// [`super::transfer`]).
    pub fn slabs(&self) -> usize {
        self.slabs
    }

    /// Computes the stencil of every marker at `positions` (world coordinates, lattice units) on
    /// `grid`, with `periodic[a]` telling whether axis `a` is periodic (otherwise it is walled:
    /// half-way bounce-back, box `[−½, n − ½]`). Parallel over markers.
    ///
    /// Writes all buffers; allocates only while they grow. On error the stencils are left
    /// empty (no marker), so a stale set can never be used by mistake.
    ///
    /// # Errors
    /// A non-finite position, or a position outside the box on a walled axis (the first such
    /// marker is named).
    ///
    /// # Panics
    /// If a grid dimension is 0 or exceeds `u32::MAX`, or there are more than `u32::MAX`
    /// markers.
    pub fn build(
        &mut self,
        grid: Grid,
        periodic: [bool; 3],
        positions: &[[f64; 3]],
    ) -> Result<(), StencilError> {
        assert!(grid.nodes() > 0, "empty grid {grid:?}");
        assert!(
            [grid.nx, grid.ny, grid.nz].iter().all(|&n| n <= u32::MAX as usize)
                && positions.len() <= u32::MAX as usize,
            "grid or marker count too large for 32-bit indices"
        );
        self.grid = grid;
        self.periodic = periodic;
        let m = positions.len();
        self.node.resize(m, [[0; MAX_WIDTH]; 3]);
        self.weight.resize(m, [[0.0; MAX_WIDTH]; 3]);
        self.len.resize(m, [0; 3]);
        self.slab.resize(m, 0);

        // The slab schedule (see `transfer`): thickness ≥ stencil width; an even count when z
        // is periodic; a single slab (serial) when there would be fewer than 4.
        let t = self.kernel.width();
        let mut s = grid.nz / t;
        if periodic[2] && s % 2 == 1 {
            s -= 1;
        }
        if s < MIN_PARALLEL_SLABS {
            s = 1;
        }
        self.slab_thickness = t;
        self.slabs = s;

        let kernel = self.kernel;
        let dims = [grid.nx, grid.ny, grid.nz];
        // The marker's error, if its position is not finite or off the box on a walled axis.
        let check = |i: usize, x: [f64; 3]| -> Option<StencilError> {
            if !x.iter().all(|c| c.is_finite()) {
                return Some(StencilError::NonFinite { marker: i, position: x });
            }
            (0..3).find_map(|a| {
                let n = dims[a] as f64;
                (!periodic[a] && !(-0.5..=n - 0.5).contains(&x[a])).then_some(StencilError::OutsideBox {
                    marker: i,
                    position: x,
                    axis: a,
                    max: n - 0.5,
                })
            })
        };
        // Parallel over chunks of markers, each chunk serial; the lowest failing marker of the
        // whole set (chunks stop at their first) is the error, whatever the thread count.
        let roma3_avx2 = kernel == DeltaKernel::Roma3 && has_avx2();
        let first_bad = self
            .node
            .par_chunks_mut(BUILD_CHUNK)
            .zip(self.weight.par_chunks_mut(BUILD_CHUNK))
            .zip(self.len.par_chunks_mut(BUILD_CHUNK))
            .zip(self.slab.par_chunks_mut(BUILD_CHUNK))
            .enumerate()
            .filter_map(|(c, (((nd, wt), ln), sl))| {
                let base = c * BUILD_CHUNK;
                let chunk = Chunk { positions: &positions[base..base + nd.len()], nd, wt, ln, sl };
                let check = |k: usize, x: [f64; 3]| check(base + k, x);
                if roma3_avx2 {
                    #[cfg(target_arch = "x86_64")]
                    // SAFETY: the processor has AVX2 (`has_avx2`).
                    return unsafe { chunk.build_roma3_avx2(dims, periodic, t, s, check) };
                }
                chunk.build(|x, nd, wt| marker_stencil(kernel, x, dims, periodic, nd, wt), t, s, check)
            })
            .min_by_key(|e| match e {
                StencilError::NonFinite { marker, .. } | StencilError::OutsideBox { marker, .. } => *marker,
            });
        if let Some(e) = first_bad {
            self.clear();
            return Err(e);
        }

        // Counting sort of the markers by slab, stable (input order within a slab). O(M)
        // integer work, serial (≈ 1 ns per marker).
        self.slab_start.clear();
        self.slab_start.resize(s + 1, 0);
        for &sl in &self.slab {
            self.slab_start[sl as usize + 1] += 1;
        }
        for k in 0..s {
            self.slab_start[k + 1] += self.slab_start[k];
        }
        self.order.resize(m, 0);
        // `slab_start[k]` serves as slab k's cursor; after the pass it holds the end of slab
        // k (= the start of k + 1), so shift the array back by one.
        let starts = &mut self.slab_start;
        for (i, &sl) in self.slab.iter().enumerate() {
            let c = &mut starts[sl as usize];
            self.order[*c as usize] = i as u32;
            *c += 1;
        }
        for k in (1..=s).rev() {
            starts[k] = starts[k - 1];
        }
        starts[0] = 0;
        Ok(())
    }

    /// Removes every marker (keeps the capacities).
    pub fn clear(&mut self) {
        self.node.clear();
        self.weight.clear();
        self.len.clear();
        self.slab.clear();
        self.order.clear();
        self.slab_start.clear();
        self.slab_start.push(0);
        self.slab_start.push(0);
        self.slabs = 1;
    }

    /// Calls `f(node, weight)` for every stencil node of marker `m` (`node` the linear index
    /// `x + nx (y + ny z)`), in the fixed order z, then y, then x, with weight
    /// `(φ_z · φ_y) · φ_x`. The one place the 3-D weights are formed: interpolation and
    /// spreading both go through it, so they are adjoint by construction.
    #[inline(always)]
    pub fn for_each_node(&self, m: usize, f: impl FnMut(usize, f64)) {
        self.for_each_node_in(self.grid.layout(), m, f)
    }

    /// As [`Stencils::for_each_node`], with node indices in `layout` (e.g. the fluid's padded
    /// arrays): the same nodes, in the same order, with bitwise the same weights.
    #[inline(always)]
    pub fn for_each_node_in(&self, layout: NodeLayout, m: usize, mut f: impl FnMut(usize, f64)) {
        let (nd, wt, lx) = (&self.node[m], &self.weight[m], self.len[m][0] as usize);
        self.for_each_yz_in(layout, m, |row, wzy| {
            for a in 0..lx {
                f(row + nd[0][a] as usize, wzy * wt[0][a]);
            }
        });
    }

    /// `f(row, w_zy)` for each (z, y) row of marker `m`'s stencil, z outer: the index of the
    /// row's node at x = 0 in `layout` and the product `φ_z · φ_y` of its weights, the first
    /// factor of every 3-D weight `δ = (φ_z · φ_y) · φ_x` in the row.
    #[inline(always)]
    fn for_each_yz_in(&self, layout: NodeLayout, m: usize, mut f: impl FnMut(usize, f64)) {
        let (nd, wt, ln) = (&self.node[m], &self.weight[m], self.len[m]);
        for c in 0..ln[2] as usize {
            let z = nd[2][c] as usize;
            let wz = wt[2][c];
            for b in 0..ln[1] as usize {
                f(layout.base + layout.sy * nd[1][b] as usize + layout.sz * z, wz * wt[1][b]);
            }
        }
    }

    /// As [`Stencils::for_each_node_in`], an x-row at a time when the marker's x-nodes are
    /// consecutive (every stencil away from a periodic seam): `f(first, weights)` with the
    /// row's first node index and the weights of its `len[0]` nodes, `first + k` the `k`-th;
    /// `false` (and nothing called) when they are not. The same nodes in the same order, with
    /// bitwise the same weights, so a caller that updates node by node gets the same bits.
    #[inline(always)]
    pub fn for_each_xrow_in(&self, layout: NodeLayout, m: usize, mut f: impl FnMut(usize, &[f64])) -> bool {
        let (nd, wt, lx) = (&self.node[m], &self.weight[m], self.len[m][0] as usize);
        if (1..lx).any(|a| nd[0][a] != nd[0][0] + a as u32) {
            return false;
        }
        let mut w = [0.0; MAX_WIDTH];
        self.for_each_yz_in(layout, m, |row, wzy| {
            for a in 0..lx {
                w[a] = wzy * wt[0][a];
            }
            f(row + nd[0][0] as usize, &w[..lx]);
        });
        true
    }

    /// `f(index)` for the first node of each x-row of marker `m`'s stencil (indices in
    /// `layout`), in the order of [`Stencils::for_each_node_in`]: where a marker's reads and
    /// updates begin, for prefetching them.
    #[inline(always)]
    pub fn for_each_row_in(&self, layout: NodeLayout, m: usize, mut f: impl FnMut(usize)) {
        let nd = &self.node[m];
        let ln = self.len[m];
        if ln[0] == 0 {
            return;
        }
        for c in 0..ln[2] as usize {
            let z = nd[2][c] as usize;
            for b in 0..ln[1] as usize {
                f(layout.base + layout.sy * nd[1][b] as usize + layout.sz * z + nd[0][0] as usize);
            }
        }
    }

    /// A hint that marker `m`'s stencil (its nodes, weights and lengths) will soon be read
    /// ([`crate::util::prefetch`]): the spreading visits the markers slab by slab, not in the
    /// order they are stored.
    #[inline(always)]
    pub fn prefetch_marker(&self, m: usize) {
        if m < self.node.len() {
            crate::util::prefetch(&self.node[m]);
            let w = &self.weight[m];
            crate::util::prefetch(w);
            crate::util::prefetch(&w[2]);
            crate::util::prefetch(&self.len[m]);
        }
    }

    /// The markers of slab `s`, in input order.
    pub(super) fn slab_markers(&self, s: usize) -> &[u32] {
        &self.order[self.slab_start[s] as usize..self.slab_start[s + 1] as usize]
    }

    /// The z-planes slab `s` owns: `[s·T, (s+1)·T)`, the last slab up to `nz`.
    #[cfg(test)]
    pub(super) fn slab_planes(&self, s: usize) -> std::ops::Range<usize> {
        let lo = s * self.slab_thickness;
        let hi = if s + 1 == self.slabs { self.grid.nz } else { lo + self.slab_thickness };
        lo..hi
    }
}

/// Whether the processor has AVX2 (the vectorised weights of [`Chunk::build_roma3_avx2`]).
#[inline]
fn has_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// One task's markers of [`Stencils::build`] and the parts of its buffers that they own.
struct Chunk<'a> {
    positions: &'a [[f64; 3]],
    nd: &'a mut [Nodes],
    wt: &'a mut [Weights],
    ln: &'a mut [[u8; 3]],
    sl: &'a mut [u32],
}

impl Chunk<'_> {
    /// Each marker's stencil by `marker(x, nodes, weights) -> lengths` and its slab (of
    /// `t` planes, `s` slabs); stops at the first marker that `check(k, x)` rejects and returns
    /// its error.
    #[inline(always)]
    fn build(
        self,
        mut marker: impl FnMut(&[f64; 3], &mut Nodes, &mut Weights) -> [u8; 3],
        t: usize,
        s: usize,
        check: impl Fn(usize, [f64; 3]) -> Option<StencilError>,
    ) -> Option<StencilError> {
        for (k, x) in self.positions.iter().enumerate() {
            if let Some(e) = check(k, *x) {
                return Some(e);
            }
            self.ln[k] = marker(x, &mut self.nd[k], &mut self.wt[k]);
            self.sl[k] = (self.nd[k][2][0] as usize / t).min(s - 1) as u32;
        }
        None
    }

    /// [`Chunk::build`] for [`DeltaKernel::Roma3`] with the nine weights of a marker in three
    /// AVX2 vectors: bitwise those of [`marker_stencil`] (why: [`roma3_marker_avx2`]); markers
    /// whose stencil crosses a wall go through [`marker_stencil`] itself.
    ///
    /// # Safety
    /// The processor must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn build_roma3_avx2(
        self,
        dims: [usize; 3],
        periodic: [bool; 3],
        t: usize,
        s: usize,
        check: impl Fn(usize, [f64; 3]) -> Option<StencilError>,
    ) -> Option<StencilError> {
        let marker = |x: &[f64; 3], nd: &mut Nodes, wt: &mut Weights| {
            // SAFETY: this function runs only where AVX2 is available.
            unsafe { roma3_marker_avx2(x, dims, periodic, nd, wt) }
                .unwrap_or_else(|| marker_stencil(DeltaKernel::Roma3, x, dims, periodic, nd, wt))
        };
        self.build(marker, t, s, check)
    }
}

/// A marker's stencil, axis by axis ([`axis_stencil`]): its lengths per axis.
#[inline(always)]
fn marker_stencil(
    kernel: DeltaKernel,
    x: &[f64; 3],
    dims: [usize; 3],
    periodic: [bool; 3],
    nd: &mut Nodes,
    wt: &mut Weights,
) -> [u8; 3] {
    let mut ln = [0u8; 3];
    for a in 0..3 {
        ln[a] = axis_stencil(kernel, x[a], dims[a], periodic[a], &mut nd[a], &mut wt[a]) as u8;
    }
    ln
}

/// The stencil of a marker at `x` for [`DeltaKernel::Roma3`] with its nine weights computed in
/// three AVX2 vectors, or `None` (nothing written) when a walled axis would drop a point: the
/// nodes as [`axis_stencil`] gives them, and the weights bitwise `φ`'s.
///
/// Why the same bits: on each axis the first node is `lo = ⌊x − 3/2⌋ + 1`, so the exact
/// offsets `x − (lo + k)` lie in `[½, 3/2)`, `[−½, ½)` and `[−3/2, −½)` for `k = 0, 1, 2`;
/// rounded as the scalar code rounds them (`r_k = x − (lo + k) as f64`, the same operation),
/// they stay in the closed intervals, whose ends are representable and rounding monotone. So
/// the middle point always takes `φ`'s inner branch, and the outer points its outer branch
/// except at the ends, `|r| = ½` (inner branch) and `|r| = 3/2` (zero), where the outer
/// formula gives the same value exactly (½ and +0). Each lane does `φ`'s operations in `φ`'s
/// order (`|r|`, products, differences, the correctly rounded square root and division), with
/// no fused multiply-add, so it rounds as the scalar code does. Tested against
/// [`axis_stencil`] in this module's tests, the ends included.
///
/// # Safety
/// The processor must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn roma3_marker_avx2(
    x: &[f64; 3],
    dims: [usize; 3],
    periodic: [bool; 3],
    nd: &mut Nodes,
    wt: &mut Weights,
) -> Option<[u8; 3]> {
    use std::arch::x86_64::*;
    let mut lo = [0i64; 3];
    for a in 0..3 {
        lo[a] = crate::util::floor_i64(x[a] - 1.5) + 1;
        // A walled axis whose three points are not all inside the box drops one.
        let inside = (0..dims[a] as i64 - 2).contains(&lo[a]);
        if !periodic[a] && !inside {
            return None;
        }
    }
    let r = |a: usize, k: i64| x[a] - (lo[a] + k) as f64;
    // Outer points (k = 0, 2) in two vectors, inner points (k = 1) in one; spare lanes repeat
    // a real point (their results are not read).
    let outer_a = _mm256_set_pd(r(0, 2), r(2, 0), r(1, 0), r(0, 0));
    let outer_b = _mm256_set_pd(r(2, 2), r(1, 2), r(2, 2), r(1, 2));
    let inner = _mm256_set_pd(r(2, 1), r(2, 1), r(1, 1), r(0, 1));
    let set = |v: f64| _mm256_set1_pd(v);
    let (one, three, five, six) = (set(1.0), set(3.0), set(5.0), set(6.0));
    let abs = |v: __m256d| _mm256_andnot_pd(set(-0.0), v);
    let (add, sub, mul, div) = (
        |a, b| _mm256_add_pd(a, b),
        |a, b| _mm256_sub_pd(a, b),
        |a, b| _mm256_mul_pd(a, b),
        |a, b| _mm256_div_pd(a, b),
    );
    // φ(r) = (1 + √(1 − 3|r|²))/3 (inner), (5 − 3|r| − √(1 − 3(1 − |r|)²))/6 (outer), in φ's order.
    let phi_inner = |r: __m256d| {
        let a = abs(r);
        div(add(one, _mm256_sqrt_pd(sub(one, mul(mul(three, a), a)))), three)
    };
    let phi_outer = |r: __m256d| {
        let a = abs(r);
        let b = sub(one, a);
        div(sub(sub(five, mul(three, a)), _mm256_sqrt_pd(sub(one, mul(mul(three, b), b)))), six)
    };
    let mut wa = [0.0f64; 4];
    let mut wb = [0.0f64; 4];
    let mut wi = [0.0f64; 4];
    _mm256_storeu_pd(wa.as_mut_ptr(), phi_outer(outer_a));
    _mm256_storeu_pd(wb.as_mut_ptr(), phi_outer(outer_b));
    _mm256_storeu_pd(wi.as_mut_ptr(), phi_inner(inner));
    let w = [[wa[0], wi[0], wa[3]], [wa[1], wi[1], wb[0]], [wa[2], wi[2], wb[1]]];
    for a in 0..3 {
        if periodic[a] {
            periodic_nodes::<3>(lo[a], dims[a], &mut nd[a]);
        } else {
            for k in 0..3 {
                nd[a][k] = (lo[a] + k as i64) as u32;
            }
        }
        wt[a][..3].copy_from_slice(&w[a]);
    }
    Some([3; 3])
}

/// The 1-D stencil of a coordinate `x` on an axis of `n` nodes: writes the node coordinates and
/// weights of the kept points and returns their number. Dispatches once to a copy of
/// [`axis_stencil_w`] per kernel, whose width is a constant: its loops unroll and each weight's
/// branch of `φ` gets its own predictor, with the same arithmetic (the same bits) as `φ`.
#[inline]
fn axis_stencil(
    kernel: DeltaKernel,
    x: f64,
    n: usize,
    periodic: bool,
    nodes: &mut [u32; MAX_WIDTH],
    weights: &mut [f64; MAX_WIDTH],
) -> usize {
    // In each arm the kernel is a constant: `φ`'s own dispatch folds away once inlined.
    match kernel {
        DeltaKernel::Linear => axis_stencil_w::<2>(DeltaKernel::Linear, x, n, periodic, nodes, weights),
        DeltaKernel::Roma3 => axis_stencil_w::<3>(DeltaKernel::Roma3, x, n, periodic, nodes, weights),
        DeltaKernel::Peskin4 => axis_stencil_w::<4>(DeltaKernel::Peskin4, x, n, periodic, nodes, weights),
    }
}

/// The `W` nodes `lo, …, lo + W − 1` of a periodic axis of `n` nodes, wrapped into `[0, n)`:
/// the first with one comparison for the stencils near the box (the integer division only for
/// coordinates further out), the others by subtraction (`n` may be < `W`).
#[inline(always)]
fn periodic_nodes<const W: usize>(lo: i64, n: usize, nodes: &mut [u32; MAX_WIDTH]) {
    let ni = n as i64;
    let mut node = (if (0..ni).contains(&lo) {
        lo
    } else if (-ni..0).contains(&lo) {
        lo + ni
    } else {
        lo.rem_euclid(ni)
    }) as usize;
    for slot in &mut nodes[..W] {
        *slot = node as u32;
        node += 1;
        while node >= n {
            node -= n;
        }
    }
}

/// [`axis_stencil`] for `kernel`, of `W = kernel.width()` points per axis.
#[inline(always)]
fn axis_stencil_w<const W: usize>(
    kernel: DeltaKernel,
    x: f64,
    n: usize,
    periodic: bool,
    nodes: &mut [u32; MAX_WIDTH],
    weights: &mut [f64; MAX_WIDTH],
) -> usize {
    debug_assert_eq!(kernel.width(), W);
    let phi = |r: f64| kernel.phi(r);
    let lo = crate::util::floor_i64(x - kernel.support()) + 1;
    if periodic {
        periodic_nodes::<W>(lo, n, nodes);
        for k in 0..W {
            weights[k] = phi(x - (lo + k as i64) as f64);
        }
        return W;
    }
    let mut kept = 0;
    let (mut sum, mut dropped) = (0.0, 0.0);
    for k in 0..W {
        let j = lo + k as i64;
        let p = phi(x - j as f64);
        if (0..n as i64).contains(&j) {
            nodes[kept] = j as u32;
            weights[kept] = p;
            sum += p;
            kept += 1;
        } else {
            dropped += p;
        }
    }
    if dropped > 0.0 {
        // `x ∈ [−½, n − ½]`: the nearest node is kept and φ(½) > 0 for every kernel, so sum > 0.
        for p in &mut weights[..kept] {
            *p /= sum;
        }
    }
    kept
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The vectorised Roma weights of `Stencils::build` against the scalar axis by axis, bit for
    /// bit: random positions, the ends of the branches (`|r| = ½` and `3/2`: half-integer and
    /// integer coordinates), tiny and far-off coordinates on periodic axes, and markers next
    /// to a wall (which take the scalar path).
    #[test]
    fn roma3_vector_weights_are_the_scalar_ones() {
        let grid = Grid::new(12, 9, 14);
        let dims = [grid.nx, grid.ny, grid.nz];
        let mut rng = crate::util::SplitMix64(11);
        let mut coords: Vec<f64> = (0..400).map(|_| rng.uniform(-0.5, 8.5)).collect();
        coords.extend((-1..=18).flat_map(|k| [k as f64, k as f64 + 0.5, k as f64 - 0.5]));
        coords.extend([
            1e-20,
            -1e-20,
            0.0,
            -0.0,
            1.5 - 1e-16,
            1.5 + 1e-15,
            2.5 - 1e-15,
            -1e3 + 0.25,
            1e4 + 0.5,
        ]);
        for periodic in [[true; 3], [false; 3], [true, false, true]] {
            let ok = |c: f64, a: usize| periodic[a] || (-0.5..=dims[a] as f64 - 0.5).contains(&c);
            let pos: Vec<[f64; 3]> = (0..coords.len())
                .map(|i| [coords[i], coords[(i * 7 + 3) % coords.len()], coords[(i * 13 + 5) % coords.len()]])
                .filter(|x| (0..3).all(|a| ok(x[a], a)))
                .collect();
            assert!(pos.len() > 100);
            let mut st = Stencils::new(DeltaKernel::Roma3);
            st.build(grid, periodic, &pos).unwrap();
            for (m, x) in pos.iter().enumerate() {
                let (mut nd, mut wt) = ([[0u32; MAX_WIDTH]; 3], [[0.0f64; MAX_WIDTH]; 3]);
                let ln = marker_stencil(DeltaKernel::Roma3, x, dims, periodic, &mut nd, &mut wt);
                assert_eq!(st.len[m], ln, "{x:?}");
                for a in 0..3 {
                    let l = ln[a] as usize;
                    assert_eq!(st.node[m][a][..l], nd[a][..l], "{x:?} axis {a}");
                    let bits = |w: &[f64]| w.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
                    assert_eq!(bits(&st.weight[m][a][..l]), bits(&wt[a][..l]), "{x:?} axis {a}");
                }
            }
        }
    }

    #[test]
    fn slab_order_is_a_stable_grouping() {
        let grid = Grid::new(8, 8, 40);
        let mut st = Stencils::new(DeltaKernel::Roma3);
        let pos: Vec<[f64; 3]> = (0..200).map(|i| [1.0, 2.0, (i * 37 % 200) as f64 * 0.2]).collect();
        st.build(grid, [true; 3], &pos).unwrap();
        assert_eq!(st.slabs(), 12); // 40 / 3 = 13, odd with periodic z -> 12
        let mut seen = vec![false; pos.len()];
        for s in 0..st.slabs() {
            let ms = st.slab_markers(s);
            assert!(ms.windows(2).all(|w| w[0] < w[1]), "input order within a slab");
            for &m in ms {
                assert!(st.slab_planes(s).contains(&(st.node[m as usize][2][0] as usize)));
                seen[m as usize] = true;
            }
        }
        assert!(seen.iter().all(|&b| b));
    }

    #[test]
    fn serial_when_few_slabs() {
        let mut st = Stencils::new(DeltaKernel::Peskin4);
        st.build(Grid::new(4, 4, 15), [true; 3], &[[1.0; 3]]).unwrap();
        assert_eq!(st.slabs(), 1);
        st.build(Grid::new(4, 4, 16), [true, true, false], &[[1.0; 3]]).unwrap();
        assert_eq!(st.slabs(), 4);
        st.build(Grid::new(4, 4, 20), [true; 3], &[[1.0; 3]]).unwrap();
        assert_eq!(st.slabs(), 4);
    }

    #[test]
    fn errors_name_the_first_bad_marker() {
        let mut st = Stencils::new(DeltaKernel::Roma3);
        let g = Grid::new(8, 8, 8);
        let mut pos = vec![[3.0; 3]; 100];
        pos[70][1] = 7.6;
        pos[90][0] = f64::NAN;
        let e = st.build(g, [true, false, true], &pos).unwrap_err();
        assert_eq!(e, StencilError::OutsideBox { marker: 70, position: pos[70], axis: 1, max: 7.5 });
        assert!(st.is_empty());
        pos[70][1] = 7.5;
        let e = st.build(g, [true, false, true], &pos).unwrap_err();
        assert!(matches!(e, StencilError::NonFinite { marker: 90, .. }));
        pos[90][0] = -1e3; // periodic axis: anywhere
        st.build(g, [true, false, true], &pos).unwrap();
        assert_eq!(st.len(), 100);
    }

    #[test]
    fn rebuild_does_not_reallocate() {
        let mut st = Stencils::new(DeltaKernel::Roma3);
        let g = Grid::new(16, 16, 32);
        let pos: Vec<[f64; 3]> =
            (0..1000).map(|i| [i as f64 * 0.013, i as f64 * 0.029, i as f64 * 0.031]).collect();
        st.build(g, [true; 3], &pos).unwrap();
        let ptrs = |st: &Stencils| {
            (
                st.node.as_ptr() as usize,
                st.weight.as_ptr() as usize,
                st.len.as_ptr() as usize,
                st.slab.as_ptr() as usize,
                st.order.as_ptr() as usize,
                st.slab_start.as_ptr() as usize,
            )
        };
        let before = ptrs(&st);
        for shift in 1..5 {
            let moved: Vec<[f64; 3]> = pos.iter().map(|p| p.map(|c| c + 0.37 * shift as f64)).collect();
            st.build(g, [true; 3], &moved[..1000 - shift]).unwrap();
            assert_eq!(ptrs(&st), before);
        }
    }

    #[test]
    fn walled_axis_drops_and_renormalises() {
        let mut nodes = [0; MAX_WIDTH];
        let mut w = [0.0; MAX_WIDTH];
        for k in DeltaKernel::ALL {
            for &x in &[-0.5, -0.2, 0.0, 0.3, 1.0, 6.5, 6.7, 7.5] {
                let len = axis_stencil(k, x, 8, false, &mut nodes, &mut w);
                assert!(len >= 1 && nodes[..len].iter().all(|&j| j < 8), "{k:?} {x}");
                let s: f64 = w[..len].iter().sum();
                assert!((s - 1.0).abs() < 1e-15, "{k:?} x={x}: Σ = {s}");
            }
        }
    }
}
