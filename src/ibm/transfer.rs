//! Interpolation (nodes → markers) and spreading (markers → nodes): an adjoint pair.
//!
//! With the stencil weights `δ_mn` of [`Stencils`] (marker `m`, node `n`):
//! - [`interpolate`]: `(I u)_m = Σ_n δ_mn u_n`;
//! - [`spread`]: `(S F)_n += Σ_m δ_mn F_m`, i.e. `S = Iᵀ`, so `⟨I u, F⟩ = ⟨u, S F⟩` for all `u`,
//!   `F` (plain Euclidean products over markers and over nodes; lattice units, a node's volume
//!   is 1). `F_m` is the force of marker `m` (not a force per area: any marker area or volume
//!   factor is the caller's), and `S F` is a force density per node — what the fluid's force
//!   field expects.
//!
//! Both read the weights through [`Stencils::for_each_node`], so they are adjoint not only in
//! exact arithmetic but weight for weight, bit for bit; the inner products then differ only by
//! the order of the summation (round-off).
//!
//! # Fields
//! The velocity comes through the [`NodeField`] trait (a value per interior node, index
//! `x + nx (y + ny z)`), implemented for slices and vectors of `[f64; 3]` and for closures
//! ([`FnField`]), so the coupling can feed the solver's velocity (which lives on a padded
//! grid, computed from populations) without copying it into a dense array first. Forces are
//! spread into a plain `&mut [[f64; 3]]` on the interior grid, which the coupling hands to the
//! solver's force field. This module imports only [`crate::lattice`].
//!
//! # Interpolation: parallel over markers
//! Each marker writes only its own output and reads the field; each sum runs over its stencil in
//! the fixed order of [`Stencils::for_each_node`]. Trivially race-free and bitwise deterministic.
//!
//! # Spreading: parallel over z-slabs in two phases, bitwise deterministic
//! Many markers add to the same node, and floating-point addition is not associative, so the
//! order in which the additions reach a node must not depend on the threads. The scheme:
//!
//! 1. **Slabs.** [`Stencils::build`] cuts the z-axis into `S` slabs of `T = W` planes (`W` the
//!    kernel's points per axis; the last slab takes the remainder, so it is at least `T` thick),
//!    with `S` made even when z is periodic. A marker belongs to the slab of its stencil's
//!    first z-node `z₀`; its stencil's planes are `z₀, …, z₀ + W − 1` (mod `nz` if periodic).
//! 2. **Reach.** A marker of slab `s` writes only to planes of slabs `s` and `s + 1` (mod `S`
//!    when z is periodic): `z₀ ≤ (s + 1)T − 1` for a non-last slab, so its last plane is at most
//!    `(s + 1)T + W − 2 < (s + 2)T`, inside slab `s + 1` (or in the thicker last slab). For the
//!    last slab, planes at or beyond `nz` exist only if z is periodic and wrap to
//!    `0, …, W − 2 < T`: slab 0. On a walled z-axis nodes outside `[0, nz)` were dropped.
//! 3. **Phases.** First all even slabs run concurrently (one rayon task per slab), then all odd
//!    slabs. *Race-freedom:* two slabs `s < s'` of the same parity have `s' ≥ s + 2`; slab `s`
//!    writes slabs `{s, s + 1}`, slab `s'` writes `{s', s' + 1 mod S}`. `s' ∉ {s, s + 1}`, and
//!    `s' + 1 ≤ S − 1` is `> s + 1`; the only way `s' + 1` could wrap to `0 = s` is `s' = S − 1`
//!    with `S − 1` even, i.e. `S` odd — excluded for periodic z, and on a walled axis nothing
//!    wraps. So no node is written by two tasks of one phase, and the phases are separated by
//!    the join at the end of the first.
//! 4. **Order.** Within a slab, markers are processed in input order (the slab grouping is a
//!    stable counting sort), each over its stencil in the fixed z, y, x order. So every node
//!    receives its additions in an order fixed by the input — phase, then slab (only one slab
//!    per phase touches it), then marker index, then stencil position — whatever the number of
//!    threads. **Marker order matters** (it is part of the input: a permutation of the markers
//!    changes the last bits of the nodes two markers share); the caller keeps it fixed (e.g.
//!    body by body, marker by marker).
//! 5. **Small grids.** With fewer than [`MIN_PARALLEL_SLABS`] slabs (`nz < 4 W`) there is a
//!    single slab and spreading runs serially in input order — chosen by the grid, never by
//!    the thread count.
//!
//! Neither function allocates.

use rayon::prelude::*;

use super::stencil::{Stencils, MIN_PARALLEL_SLABS};
use crate::lattice::NodeLayout;
use crate::util::SharedMut;

/// A vector value per node of the interior grid (index `x + nx (y + ny z)`), read by
/// [`interpolate`]. Must be safe to read from several threads.
pub trait NodeField: Sync {
    /// Number of nodes (checked against the stencils' grid).
    fn nodes(&self) -> usize;
    /// The value at node `n`.
    fn value(&self, n: usize) -> [f64; 3];
    /// A hint that the values of nodes `n, n + 1, n + 2` (an x-row of a stencil) will soon be
    /// read; nothing by default (computed fields).
    #[inline(always)]
    fn prefetch(&self, _n: usize) {}
}

impl NodeField for [[f64; 3]] {
    fn nodes(&self) -> usize {
        self.len()
    }
    #[inline(always)]
    fn value(&self, n: usize) -> [f64; 3] {
        self[n]
    }
    #[inline(always)]
    fn prefetch(&self, n: usize) {
        // Three nodes of 24 bytes: at most two cache lines, the first and the third node's.
        crate::util::prefetch(self.as_ptr().wrapping_add(n));
        crate::util::prefetch(self.as_ptr().wrapping_add(n + 2));
    }
}

impl NodeField for Vec<[f64; 3]> {
    fn nodes(&self) -> usize {
        self.len()
    }
    #[inline(always)]
    fn value(&self, n: usize) -> [f64; 3] {
        self[n]
    }
    #[inline(always)]
    fn prefetch(&self, n: usize) {
        self.as_slice().prefetch(n)
    }
}

/// A [`NodeField`] computed on demand by a closure `f(n)` over `nodes` nodes (e.g. the velocity
/// from the solver's populations).
#[derive(Clone, Copy, Debug)]
pub struct FnField<F> {
    /// Number of nodes.
    pub nodes: usize,
    /// The value at node `n`.
    pub f: F,
}

impl<F: Fn(usize) -> [f64; 3] + Sync> NodeField for FnField<F> {
    fn nodes(&self) -> usize {
        self.nodes
    }
    #[inline(always)]
    fn value(&self, n: usize) -> [f64; 3] {
        (self.f)(n)
    }
}

/// Interpolates `field` to every marker: `out[m] = Σ_n δ_mn field(n)`. Parallel over markers,
/// bitwise deterministic, no allocation.
///
/// Reads: the field at the stencil nodes. Writes: all of `out` (overwritten).
///
/// # Panics
/// If `out.len()` differs from the number of markers or `field.nodes()` from the grid's.
pub fn interpolate<F: NodeField + ?Sized>(field: &F, stencils: &Stencils, out: &mut [[f64; 3]]) {
    assert_eq!(out.len(), stencils.len(), "one output per marker");
    assert_eq!(field.nodes(), stencils.grid().nodes(), "field on the stencils' grid");
    let (layout, markers) = (stencils.grid().layout(), out.len());
    out.par_iter_mut().with_min_len(256).enumerate().for_each(|(m, o)| {
        if m + PREFETCH_AHEAD < markers {
            stencils.for_each_row_in(layout, m + PREFETCH_AHEAD, |n| field.prefetch(n));
        }
        let mut acc = [0.0; 3];
        stencils.for_each_node(m, |n, w| {
            let u = field.value(n);
            acc[0] += w * u[0];
            acc[1] += w * u[1];
            acc[2] += w * u[2];
        });
        *o = acc;
    });
}

/// Where spreading writes: a per-node force density that tasks writing disjoint z-slabs may
/// update concurrently. Implemented for a plain per-node slice ([`spread`]) and, in
/// `coupling`, for the fluid's own force field (no intermediate full-grid buffer).
pub trait ForceSink: Sync {
    /// The layout of the sink's node indices.
    fn layout(&self) -> NodeLayout;

    /// `sink[index] += w · f`.
    ///
    /// # Safety
    /// `index` is the layout's index of a node of the stencils' grid, and no other thread
    /// accesses that node during the call.
    unsafe fn add(&self, index: usize, w: f64, f: [f64; 3]);

    /// `sink[index + k] += w[k] · f` for each `k`: an x-row of consecutive nodes
    /// ([`Stencils::for_each_xrow_in`]). Each node gets the update [`ForceSink::add`] gives it,
    /// so the result is the same whichever is called; a sink may override this to update the
    /// row's values together.
    ///
    /// # Safety
    /// As [`ForceSink::add`], for every node of the row.
    #[inline(always)]
    unsafe fn add_row(&self, index: usize, w: &[f64], f: [f64; 3]) {
        for (k, &wk) in w.iter().enumerate() {
            self.add(index + k, wk, f);
        }
    }

    /// A hint that the node at `index` and the next ones of its x-row will soon be updated;
    /// nothing by default.
    #[inline(always)]
    fn prefetch(&self, _index: usize) {}
}

/// How many markers ahead [`interpolate`] prefetches the rows of a marker's stencil in a
/// stored field, and [`spread_into`] a marker's stencil and force (its force-field rows half as
/// far ahead, once that stencil has arrived). The field is read and updated at scattered rows
/// that the hardware prefetchers cannot guess, and the spreading visits the markers slab by
/// slab, out of their storage order; beyond the last-level cache (s = 1/2 and up: 45 MB of
/// velocities, 58 MB of stencils) each is otherwise a memory latency. Only when values are
/// fetched changes, not which or in what order: the same bits.
const PREFETCH_AHEAD: usize = 16;

/// Spreads the marker forces onto the nodes: `field[n] += Σ_m δ_mn forces[m]` (adds; the
/// caller zeroes `field` if it wants `S F` alone). Parallel over z-slabs in two phases,
/// bitwise identical for any thread count (see the module docs for the scheme and its proof),
/// no allocation.
///
/// Reads: `forces`. Writes: `field` at the stencil nodes.
///
/// # Panics
/// If `forces.len()` differs from the number of markers or `field.len()` from the grid's
/// node count.
pub fn spread(forces: &[[f64; 3]], stencils: &Stencils, field: &mut [[f64; 3]]) {
    assert_eq!(field.len(), stencils.grid().nodes(), "field on the stencils' grid");
    let shared = SharedField { field: SharedMut::new(field), layout: stencils.grid().layout() };
    spread_into(forces, stencils, &shared);
}

/// [`spread`] into any [`ForceSink`]: the same slab schedule, the same order of updates per
/// node, so the result (in the sink's precision) is bitwise independent of the thread count.
///
/// # Panics
/// If `forces.len()` differs from the number of markers.
pub fn spread_into<S: ForceSink + ?Sized>(forces: &[[f64; 3]], stencils: &Stencils, sink: &S) {
    assert_eq!(forces.len(), stencils.len(), "one force per marker");
    let layout = sink.layout();
    let slabs = stencils.slabs();
    if slabs < MIN_PARALLEL_SLABS {
        for s in 0..slabs {
            for &m in stencils.slab_markers(s) {
                let f = forces[m as usize];
                // SAFETY: serial; the index is a stencil node in the sink's layout.
                stencils.for_each_node_in(layout, m as usize, |n, w| unsafe { sink.add(n, w, f) });
            }
        }
        return;
    }
    for phase in 0..2 {
        // One task per slab (`with_max_len(1)`): the markers crowd into a few slabs (a settled
        // bed, the impeller's plane), and rayon's adaptive splitting alone can leave a whole
        // run of the heavy slabs to one thread (the spreading then takes as long on 2 threads
        // as on 1).
        (0..(slabs - phase).div_ceil(2)).into_par_iter().with_max_len(1).for_each(|k| {
            let s = phase + 2 * k;
            let markers = stencils.slab_markers(s);
            for (i, &m) in markers.iter().enumerate() {
                if let Some(&ahead) = markers.get(i + PREFETCH_AHEAD) {
                    stencils.prefetch_marker(ahead as usize);
                    crate::util::prefetch(&forces[ahead as usize]);
                }
                if let Some(&near) = markers.get(i + PREFETCH_AHEAD / 2) {
                    stencils.for_each_row_in(layout, near as usize, |n| sink.prefetch(n));
                }
                let f = forces[m as usize];
                // SAFETY (both): stencil nodes of the grid, in the sink's layout; by the phase
                // argument of the module docs no other task of this phase writes a node in
                // slabs `s` or `s + 1`, which contain them.
                let by_rows =
                    stencils.for_each_xrow_in(layout, m as usize, |n, w| unsafe { sink.add_row(n, w, f) });
                if !by_rows {
                    stencils.for_each_node_in(layout, m as usize, |n, w| unsafe { sink.add(n, w, f) });
                }
            }
        });
    }
}

/// `cell += w · f`, component-wise; the one spreading update (the serial and parallel paths
/// must round alike).
#[inline(always)]
fn add(cell: &mut [f64; 3], w: f64, f: [f64; 3]) {
    cell[0] += w * f[0];
    cell[1] += w * f[1];
    cell[2] += w * f[2];
}

/// A per-node slice shared by the tasks of one spreading phase, which write disjoint nodes
/// (see `spread_into`); the borrow of the field it was made from outlives every task.
struct SharedField<'a> {
    field: SharedMut<'a, [f64; 3]>,
    layout: NodeLayout,
}

impl ForceSink for SharedField<'_> {
    fn layout(&self) -> NodeLayout {
        self.layout
    }

    #[inline(always)]
    unsafe fn add(&self, n: usize, w: f64, f: [f64; 3]) {
        let mut cell = self.field.read(n);
        add(&mut cell, w, f);
        self.field.write(n, cell);
    }
}
