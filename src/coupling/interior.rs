//! Phases 3 and 7 of the coupled step: the interior-fluid sums of each free or fixed body
//! (module [`super`], "Free bodies: the interior fluid").
//!
//! Both sums of a step are taken with the body at `xⁿ` (it moves only in phase 8), over the
//! same nodes with the same weights `α`. Phase 3 walks the body's rows ([`row_spans`],
//! [`emit_runs`]), evaluates `α` (the signed distance at the partial nodes) and records the
//! nodes and weights in the body's [`InteriorNodes`]; phase 7 only gathers over that record.
//! One function adds a run's nodes for both ([`Sums::add_run`]): the same nodes, weights and
//! order, so the same bits as walking the body twice.

use rayon::prelude::*;

use super::band::{emit_runs, row_spans};
use super::moments::Moments;
use super::Coupled;
use crate::lattice::{Grid, Run};
use crate::lbm::{Fluid, Real};
use crate::rigid::{Motion, RigidBody, Vec3};

/// Which of the two sums of a step: before the forcing (fluid at `tⁿ`) or after the fluid step
/// (fluid at `tⁿ⁺¹`); the bodies are at `xⁿ` for both.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Moment {
    /// Phase 3: walks the body and records its [`InteriorNodes`].
    Before,
    /// Phase 7: gathers over the nodes recorded in phase 3.
    After,
}

impl<T: Real> Coupled<T> {
    /// The interior sums `(P, L, V)` of every body that has an interior term, into
    /// `self.interior[b].before` (recording the body's nodes in `self.interior_nodes[b]`) or
    /// `.after` (from that record); parallel over bodies, each body serial.
    ///
    /// In a dense step (the band is the whole grid) the momentum comes from the stored
    /// moments of the fluid's current state (module `moments`), read here first if needed:
    /// the same numbers as reading the fluid at each node.
    pub(super) fn interior_sums(&mut self, moment: Moment) {
        let dense = self.band.whole_grid;
        if dense && !self.moments.current(&self.fluid) {
            self.moments.fill(&self.fluid, &mut self.velocity);
        }
        let source = if dense { Source::Moments(&self.moments) } else { Source::Fluid(&self.fluid) };
        let (source, grid, periodic) = (&source, self.fluid.grid(), self.periodic);
        self.interior
            .par_iter_mut()
            .zip(self.interior_nodes.par_iter_mut())
            .zip(self.bodies.par_iter())
            .for_each(|((im, nodes), body)| {
                if has_interior_term(body) {
                    match moment {
                        Moment::Before => im.before = nodes.record(source, grid, body, periodic),
                        Moment::After => {
                            debug_assert_eq!(nodes.centre, body.position, "the body moved since phase 3");
                            im.after = nodes.sums(source);
                        }
                    }
                }
            });
    }
}

/// Whether a body's loads include the interior-fluid term: free and fixed bodies do; a
/// prescribed body (an impeller) does not, since its loads are only reported, and the paper's
/// fluid torque on an impeller is the immersed-boundary torque alone. Its sums stay zero.
pub(super) fn has_interior_term(body: &RigidBody) -> bool {
    !matches!(body.motion(), Motion::Prescribed(_))
}

/// One run of a body's interior nodes: the nodes (in the grid) and the shift to their
/// unwrapped coordinates (`unwrapped = wrapped + shift`, [`emit_runs`]).
#[derive(Clone, Copy, Debug)]
struct InteriorRun {
    run: Run,
    shift: [i64; 3],
}

/// The interior nodes of one body at `xⁿ` and their weights `α = clamp(½ − sd, 0, 1)`, in the
/// order phase 3 visits them, so that phase 7 sums over them without walking the body's rows
/// or evaluating the signed distance again (module docs). The buffers are reused from step
/// to step (they only grow).
#[derive(Clone, Debug, Default)]
pub(super) struct InteriorNodes {
    /// The runs, in visiting order.
    runs: Vec<InteriorRun>,
    /// `α` of every node of every run, run after run (zeros included: the sums skip them).
    alpha: Vec<f64>,
    /// The body's centre when recorded, about which the moment arms are taken.
    centre: Vec3,
}

impl InteriorNodes {
    /// Records `body`'s interior nodes and weights (the nodes with `sd < ½`; nodes deeper
    /// than `sd < −½` have `α = 1` without evaluating `sd`) and returns their sums
    /// `(P, L, V)` from `source`, each run summed as soon as it is recorded.
    fn record<T: Real>(
        &mut self,
        source: &Source<T>,
        grid: Grid,
        body: &RigidBody,
        periodic: [bool; 3],
    ) -> (Vec3, Vec3, f64) {
        let shape = body.shape().as_ref();
        self.runs.clear();
        self.alpha.clear();
        self.centre = body.position;
        let (runs, alpha, centre) = (&mut self.runs, &mut self.alpha, self.centre);
        let mut sums = Sums::default();
        row_spans(body, grid, periodic, 0.5, Some(-0.5), |s| {
            emit_runs(grid, periodic, (s.xa, s.xb, s.y, s.z), |run: Run, shift| {
                // The run's momenta are read right after its weights, whose signed distances
                // take about a memory latency to evaluate: fetch them meanwhile.
                source.prefetch(run);
                let first = alpha.len();
                for x in run.x0..run.x0 + run.len {
                    let xu = x as i64 + shift[0];
                    alpha.push(if s.xs <= xu && xu <= s.xe {
                        1.0
                    } else {
                        (0.5 - shape.signed_distance(&(s.origin + s.dir * xu as f64))).clamp(0.0, 1.0)
                    });
                }
                let r = InteriorRun { run, shift };
                runs.push(r);
                sums.add_run(source, r, &alpha[first..], centre);
            });
        });
        sums.into()
    }

    /// The sums `(P, L, V)` from `source` over the recorded nodes and weights: the same
    /// arithmetic in the same order as [`InteriorNodes::record`], so the same bits as walking
    /// the body again.
    fn sums<T: Real>(&self, source: &Source<T>) -> (Vec3, Vec3, f64) {
        let mut sums = Sums::default();
        let mut first = 0;
        for (i, &r) in self.runs.iter().enumerate() {
            if let Some(ahead) = self.runs.get(i + PREFETCH_RUNS) {
                source.prefetch(ahead.run);
            }
            let end = first + r.run.len as usize;
            sums.add_run(source, r, &self.alpha[first..end], self.centre);
            first = end;
        }
        sums.into()
    }
}

/// Running interior sums `P = Σ α j`, `L = Σ α r × j`, `V = Σ α` of one body.
#[derive(Clone, Copy, Debug, Default)]
struct Sums {
    p: Vec3,
    l: Vec3,
    v: f64,
}

impl Sums {
    /// Adds the nodes of `nodes` with weights `alpha` (one per node, in x order), moment arms
    /// about `c` from the unwrapped coordinates; nodes with `α = 0` are skipped. The only
    /// place this arithmetic is written (phases 3 and 7 both call it).
    #[inline]
    fn add_run<T: Real>(&mut self, source: &Source<T>, nodes: InteriorRun, alpha: &[f64], c: Vec3) {
        let InteriorRun { run, shift } = nodes;
        let (yu, zu) = ((run.y as i64 + shift[1]) as f64, (run.z as i64 + shift[2]) as f64);
        source.for_each_j(run, |x, j| {
            let xu = x as i64 + shift[0];
            let alpha = alpha[x - run.x0 as usize];
            if alpha > 0.0 {
                let r = Vec3::new(xu as f64 - c.x, yu - c.y, zu - c.z);
                self.v += alpha;
                let m = Vec3::from(j) * alpha;
                self.p += m;
                self.l += r.cross(&m);
            }
        });
    }
}

impl From<Sums> for (Vec3, Vec3, f64) {
    fn from(s: Sums) -> Self {
        (s.p, s.l, s.v)
    }
}

/// Where the interior sums read the momentum `j`: the fluid's populations, or the moments
/// stored for its current state (dense steps, module `moments`): the same numbers.
enum Source<'a, T: Real> {
    Fluid(&'a Fluid<T>),
    Moments(&'a Moments),
}

/// How many recorded runs ahead phase 7 prefetches the stored momenta: beyond the last-level
/// cache (s = 1/2: 45 MB of momenta) each body's rows are otherwise a memory latency each.
const PREFETCH_RUNS: usize = 4;

impl<T: Real> Source<'_, T> {
    /// A hint that the momenta of `run` will soon be read (stored moments only; nothing for the
    /// fluid's populations, 19 arrays).
    #[inline(always)]
    fn prefetch(&self, run: Run) {
        if let Source::Moments(moments) = self {
            moments.prefetch(run);
        }
    }

    /// `f(x, j)` for every node of `run`, x in order.
    #[inline]
    fn for_each_j(&self, run: Run, mut f: impl FnMut(usize, [f64; 3])) {
        match self {
            Source::Fluid(fluid) => fluid.for_each_in_run(run, |x, _rho, j, _f| f(x, j)),
            Source::Moments(moments) => moments.for_each_j(run, f),
        }
    }
}
