//! Where a body touches the lattice, row by row: the immersed-boundary **band** (the nodes
//! that stencils of the body's markers can reach) and the **interior** (the nodes whose
//! fluid momentum counts as inside the body), both built from [`Shape::chord`] along x-rows,
//! so that the work scales with the surface (band) and the volume (interior), never with the
//! grid or with the body's bounding box.
//!
//! # Coordinates and periodic images
//! A body's centre is not wrapped: on a periodic axis it may lie anywhere, and its nodes are
//! found at unwrapped integer coordinates and wrapped into the grid (`rem_euclid`). On a
//! walled axis coordinates outside `[0, n)` are dropped. Every emitted [`Run`] lies in the
//! grid; its `shift` gives the unwrapped coordinates (`unwrapped = wrapped + shift`) that
//! moment arms need.

use crate::lattice::{Grid, Run};
use crate::rigid::{RigidBody, Shape, Vec3};
use crate::util::{ceil_i64, floor_i64};

/// Slack added to chords: a node exactly on a chord end is taken (outer) or not skipped
/// (inner). Chords are computed in `f64` from coordinates of order 10²: 1e-9 is far above
/// their round-off and far below a lattice spacing.
const SLACK: f64 = 1e-9;

/// One row of a body: unwrapped `y`, `z`, the outer node range `[xa, xb]` (unwrapped, maybe
/// empty if `xa > xb`) and the inner range `[xs, xe]` to skip (empty if `xs > xe`).
#[derive(Clone, Copy, Debug)]
pub(super) struct RowSpan {
    pub y: i64,
    pub z: i64,
    pub xa: i64,
    pub xb: i64,
    pub xs: i64,
    pub xe: i64,
    /// Body-frame position of the row's point at world `x = 0`, and the body-frame direction
    /// of world `+x`: the node at unwrapped `x` is at `origin + x · dir` in the body frame.
    pub origin: Vec3,
    pub dir: Vec3,
}

/// Calls `f` for every x-row of `body` that meets `{sd < outer}` (`outer ≥ 0`), with the
/// nodes strictly inside the chord of `{sd < outer}` and, if `inner` is given (`< 0`), the
/// sub-range strictly inside `{sd < inner}`. Rows outside the grid on walled axes are skipped;
/// x is not clipped here (see [`emit_runs`]).
pub(super) fn row_spans(
    body: &RigidBody,
    grid: Grid,
    periodic: [bool; 3],
    outer: f64,
    inner: Option<f64>,
    mut f: impl FnMut(RowSpan),
) {
    let shape: &dyn Shape = body.shape().as_ref();
    let r = body.rotation_matrix();
    let c = body.position;
    let e = shape.half_extents(&r, outer);
    let range = |a: usize| -> (i64, i64) {
        let lo = floor_i64(c[a] - e[a]);
        let hi = ceil_i64(c[a] + e[a]);
        if periodic[a] {
            // Unwrapped; if the range is longer than the period, some rows are visited twice
            // with different images (harmless for the band, which may repeat nodes).
            (lo, hi)
        } else {
            (lo.max(0), hi.min(grid.dim(a) as i64 - 1))
        }
    };
    let (y0, y1) = range(1);
    let (z0, z1) = range(2);
    // Direction of the rows, +x world, in the body frame: Rᵀ e_x.
    let dir = Vec3::new(r[(0, 0)], r[(0, 1)], r[(0, 2)]);
    for z in z0..=z1 {
        for y in y0..=y1 {
            // Row origin: world (0, y, z) relative to the centre, in the body frame.
            let o = r.tr_mul(&Vec3::new(-c.x, y as f64 - c.y, z as f64 - c.z));
            let Some((t0, t1)) = shape.chord(&o, &dir, outer) else { continue };
            let xa = floor_i64(t0 - SLACK) + 1;
            let xb = ceil_i64(t1 + SLACK) - 1;
            if xa > xb {
                continue;
            }
            let (xs, xe) = match inner.and_then(|off| shape.chord(&o, &dir, off)) {
                Some((s0, s1)) => (floor_i64(s0 + SLACK) + 1, ceil_i64(s1 - SLACK) - 1),
                None => (1, 0),
            };
            f(RowSpan { y, z, xa, xb, xs, xe, origin: o, dir });
        }
    }
}

/// Splits the unwrapped node range `[a, b]` of row `(y, z)` into runs inside the grid
/// (wrapping on periodic axes, clipping on walled ones) and calls `f(run, shift)`.
pub(super) fn emit_runs(
    grid: Grid,
    periodic: [bool; 3],
    (a, b, y, z): (i64, i64, i64, i64),
    mut f: impl FnMut(Run, [i64; 3]),
) {
    if a > b {
        return;
    }
    let wrap = |v: i64, ax: usize| -> i64 {
        if periodic[ax] {
            v.rem_euclid(grid.dim(ax) as i64)
        } else {
            v
        }
    };
    let (yw, zw) = (wrap(y, 1), wrap(z, 2));
    let nx = grid.nx as i64;
    let (a, b) = if periodic[0] { (a, b.min(a + nx - 1)) } else { (a.max(0), b.min(nx - 1)) };
    let mut x = a;
    while x <= b {
        let xw = wrap(x, 0);
        let len = (b - x + 1).min(nx - xw);
        f(Run { x0: xw as u32, len: len as u32, y: yw as u32, z: zw as u32 }, [x - xw, y - yw, z - zw]);
        x += len;
    }
}

/// The band of one body: every node within `half_width` of its surface (the chord of
/// `{sd < half_width}` minus that of `{sd < −half_width}`), as runs appended to `out`.
pub(super) fn band_runs(
    body: &RigidBody,
    grid: Grid,
    periodic: [bool; 3],
    half_width: f64,
    out: &mut Vec<Run>,
) {
    out.clear();
    row_spans(body, grid, periodic, half_width, Some(-half_width), |s| {
        let push = |run: Run, _: [i64; 3]| out.push(run);
        if s.xs > s.xe {
            emit_runs(grid, periodic, (s.xa, s.xb, s.y, s.z), push);
        } else {
            let mut push = push;
            emit_runs(grid, periodic, (s.xa, s.xb.min(s.xs - 1), s.y, s.z), &mut push);
            emit_runs(grid, periodic, (s.xa.max(s.xe + 1), s.xb, s.y, s.z), &mut push);
        }
    });
}

/// Number of nodes in `runs`.
pub(super) fn run_nodes(runs: &[Run]) -> usize {
    runs.iter().map(|r| r.len as usize).sum()
}

/// Runs of all bodies, bucketed by z-plane (a stable counting sort: body order, then row
/// order, within a plane), so that per-plane work is parallel and deterministic; or, when
/// the runs were not built, the whole grid. Buffers are reused across steps. The default is
/// an empty band (built, no runs).
#[derive(Clone, Debug, Default)]
pub(super) struct Band {
    /// Per body, its runs (scratch, filled in parallel).
    pub per_body: Vec<Vec<Run>>,
    /// All runs, grouped by plane: plane `z` owns `runs[start[z]..start[z + 1]]`.
    pub runs: Vec<Run>,
    /// Plane offsets (`nz + 1` entries once built; empty before).
    pub start: Vec<usize>,
    /// The runs were not built: the band stands for every node of the grid (the bands were
    /// judged to hold more than a tenth of the grid (`DENSE_BAND_FRACTION`), so the step evaluated the velocity at every
    /// node; or it is unknown, after a restore). No runs then.
    pub whole_grid: bool,
}

impl Band {
    /// Makes this the whole grid without building runs ([`Band::whole_grid`]).
    pub fn set_whole_grid(&mut self) {
        self.runs.clear();
        self.start.clear();
        self.whole_grid = true;
    }

    /// Regroups `per_body` by plane into `runs`/`start`: the band is built.
    pub fn bucket(&mut self, nz: usize) {
        self.whole_grid = false;
        self.start.clear();
        self.start.resize(nz + 1, 0);
        for r in self.per_body.iter().flatten() {
            self.start[r.z as usize + 1] += 1;
        }
        for z in 0..nz {
            self.start[z + 1] += self.start[z];
        }
        let total = self.start[nz];
        self.runs.resize(total, Run::default());
        // `start[z]` doubles as the cursor of plane z; shifted back afterwards.
        for r in self.per_body.iter().flatten() {
            let c = &mut self.start[r.z as usize];
            self.runs[*c] = *r;
            *c += 1;
        }
        for z in (1..=nz).rev() {
            self.start[z] = self.start[z - 1];
        }
        self.start[0] = 0;
    }

    /// The runs of plane `z` (none before the first build, and none for the whole grid).
    pub fn plane(&self, z: usize) -> &[Run] {
        if z + 1 >= self.start.len() {
            return &[];
        }
        &self.runs[self.start[z]..self.start[z + 1]]
    }

    /// Number of nodes in all runs (with repetitions where bodies' bands overlap; none for
    /// the whole grid).
    pub fn nodes(&self) -> usize {
        run_nodes(&self.runs)
    }
}
