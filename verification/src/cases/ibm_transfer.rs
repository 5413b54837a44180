//! # IBM transfer operators: moment conditions, adjointness, determinism
//!
//! **What.** The immersed-boundary transfer of [`slurry::ibm`]: a marker at `X` has the 3-D
//! weights `δ = φ(x−X) φ(y−Y) φ(z−Z)` on the nodes of its stencil; interpolation is
//! `(I u)_m = Σ_n δ_mn u_n`, spreading `(S F)_n = Σ_m δ_mn F_m`. For each kernel
//! ([`slurry::ibm::DeltaKernel`]: linear, Roma 3-point, Peskin 4-point), seeded random markers
//! (splitmix64), 32³ grids.
//!
//! **Reference.** Exact identities: the kernels' discrete moment conditions (Roma, Peskin &
//! Berger 1999, eq. 22; Peskin 2002, §6) give `Σ_n δ = 1` and `Σ_n (x_n − X) δ = 0` for every
//! marker position; `S = Iᵀ` gives `⟨I u, F⟩ = ⟨u, S F⟩` for all `u`, `F`; renormalised wall
//! stencils keep `Σ_n (S F)_n = Σ_m F_m`; the z-slab spreading schedule makes `S F` independent
//! of the thread count, bit for bit.
//!
//! **Metrics and tolerances.**
//! - `*_partition_of_unity`, `*_first_moment`: max over 10⁴ markers of `|Σδ − 1|` and
//!   `max_a |Σ (x_a − X_a) δ|` (minimal-image displacements) on a periodic box (markers
//!   anywhere, stencils wrapping) and a walled box (markers at least one support from the
//!   walls). Tolerance 1e-14: each 1-D weight carries a few ulps of absolute error from its
//!   square root, the kernel arguments `X − j` (|·| < 2) are exact or rounded once, the
//!   measured displacements are formed from the integer part and fraction of `X` (no rounding
//!   at the magnitude of `X`), and ≤ 64 products of three weights add up to ≲ 1e-15; a wrong
//!   formula or node gives ≥ 1e-3.
//! - `*_adjoint_defect_{periodic,walled}`: `|⟨I u, F⟩ − ⟨u, S F⟩| / |⟨I u, F⟩|` for `u`, `F`
//!   uniform in `[−1, 1]`, 2·10⁴ markers (walled: anywhere in `[−½, 31½]³`, so many stencils
//!   are cut and renormalised). Inner products with compensated summation, so only the
//!   operators' own round-off is left: sums of ≤ 64 terms per marker and per node, ~1e-16 per
//!   addition and random in sign, ~1e-15 relative. Tolerance 1e-13; weights that differ
//!   between the two operators (renormalised on one side only, say) give ≥ 1e-3.
//! - `*_force_conservation_walled`: `max_c |Σ_n (S F)_n,c − Σ_m F_m,c| / Σ_m |F_m,c|` with
//!   markers up to the walls. Tolerance 1e-13: the renormalised weights of each marker sum to
//!   1 within ~1e-15, and the two sums of 2·10⁴ … 3·10⁴ terms are compensated; without the
//!   renormalisation the loss is ~1e-2.
//! - `*_spread_mismatches_1_vs_2_threads` (and 4 threads), periodic and walled: number of
//!   node values whose bits differ. Tolerance 0: the schedule fixes the order of the additions
//!   to every node independently of the threads (proof in `slurry::ibm::transfer`).
//!
//! **Cost (reported, not checked).** ≈ 10⁵ markers (111 spheres of diameter 12 with 900
//! markers each, spacing ≈ 0.71, as the paper's 0.5–0.75) at random centres in a 128³ periodic
//! box; minimum of 7 repetitions (the machine may be shared: the minimum is the least disturbed) of stencil build, interpolation and spreading, in ns per
//! marker, with 1 and 2 threads.

use std::time::Instant;

use slurry::ibm::{interpolate, spread, DeltaKernel, Stencils};
use slurry::lattice::Grid;

use crate::{CaseOutput, Check, Table, Tier};

const CASE: &str = "ibm_transfer";

use slurry::util::{compensated_sum as csum, SplitMix64 as Rng};

fn dot(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    csum(a.iter().zip(b).flat_map(|(x, y)| (0..3).map(move |k| x[k] * y[k])))
}

fn stencils(kernel: DeltaKernel, grid: Grid, periodic: [bool; 3], pos: &[[f64; 3]]) -> Stencils {
    let mut st = Stencils::new(kernel);
    st.build(grid, periodic, pos).expect("markers inside the box");
    st
}

fn in_pool<R: Send>(threads: usize, f: impl FnOnce() -> R + Send) -> R {
    rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("thread pool").install(f)
}

/// Markers in the box: periodic axes anywhere in `[−n, 2n)` (stencils wrap), walled axes in
/// `[lo, n − 1 − lo]` (`lo = −½`: up to the walls).
fn markers(rng: &mut Rng, grid: Grid, periodic: [bool; 3], lo: f64, count: usize) -> Vec<[f64; 3]> {
    (0..count)
        .map(|_| {
            std::array::from_fn(|a| {
                let n = grid.dim(a) as f64;
                if periodic[a] {
                    rng.uniform(-n, 2.0 * n)
                } else {
                    rng.uniform(lo, n - 1.0 - lo)
                }
            })
        })
        .collect()
}

/// Max `|Σδ − 1|` and max first-moment error over the markers.
fn moments(st: &Stencils, pos: &[[f64; 3]]) -> (f64, f64) {
    let grid = st.grid();
    let periodic = st.periodic();
    let (mut e0, mut e1) = (0.0f64, 0.0f64);
    for (m, x) in pos.iter().enumerate() {
        let mut s = 0.0;
        let mut mom = [0.0; 3];
        st.for_each_node(m, |n, w| {
            let c = grid.coords(n);
            s += w;
            for a in 0..3 {
                // Integer part and fraction of X: no rounding at the magnitude of X.
                let fl = x[a].floor();
                let mut k = c[a] as i64 - fl as i64;
                if periodic[a] {
                    let l = grid.dim(a) as i64;
                    k = (k + l / 2).rem_euclid(l) - l / 2;
                }
                mom[a] += (k as f64 - (x[a] - fl)) * w;
            }
        });
        e0 = e0.max((s - 1.0).abs());
        e1 = mom.iter().fold(e1, |e, v| e.max(v.abs()));
    }
    (e0, e1)
}

fn kernel_id(k: DeltaKernel) -> f64 {
    DeltaKernel::ALL.iter().position(|&q| q == k).expect("listed") as f64
}

/// `count` points of a Fibonacci lattice on a sphere of radius `r` around `c`.
fn sphere(c: [f64; 3], r: f64, count: usize, out: &mut Vec<[f64; 3]>) {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    for i in 0..count {
        let z = 1.0 - (2.0 * i as f64 + 1.0) / count as f64;
        let rho = (1.0 - z * z).sqrt();
        let phi = golden * i as f64;
        out.push([c[0] + r * rho * phi.cos(), c[1] + r * rho * phi.sin(), c[2] + r * z]);
    }
}

fn min(v: &[f64]) -> f64 {
    v.iter().copied().fold(f64::INFINITY, f64::min)
}

/// Runs the case.
pub fn run(_tier: Tier) -> CaseOutput {
    let mut out = CaseOutput::default();
    let grid = Grid::new(32, 32, 32);
    let walled = [false; 3];
    let periodic = [true; 3];
    let mut rng = Rng(0x1b3_2024);

    // Moment conditions.
    let pos_p = markers(&mut rng, grid, periodic, 0.0, 10_000);
    let pos_w = markers(&mut rng, grid, walled, 2.0, 10_000);
    let mut t = Table::new(
        "moments (kernel: 0 = linear, 1 = roma3, 2 = peskin4; max over 1e4 markers)",
        &[
            ("kernel", false),
            ("pou_periodic", false),
            ("moment1_periodic", false),
            ("pou_walled", false),
            ("moment1_walled", false),
        ],
    );
    for k in DeltaKernel::ALL {
        let (p0, p1) = moments(&stencils(k, grid, periodic, &pos_p), &pos_p);
        let (w0, w1) = moments(&stencils(k, grid, walled, &pos_w), &pos_w);
        t.push(vec![kernel_id(k), p0, p1, w0, w1]);
        let why0 = "each 1-D weight has a few ulps of absolute error (square roots); ≤ 64 products \
                    of three add up to ≲ 1e-15; a wrong formula or node gives ≥ 1e-3";
        let why1 = "kernel arguments X − j exact or rounded once at magnitude < 2, weights a few \
                    ulps: ≲ 1e-15; a biased stencil gives ≥ 1e-3";
        out.checks.push(Check::at_most(
            CASE,
            format!("{}_partition_of_unity", k.name()),
            p0.max(w0),
            1e-14,
            why0,
        ));
        out.checks.push(Check::at_most(CASE, format!("{}_first_moment", k.name()), p1.max(w1), 1e-14, why1));
    }
    out.tables.push(t);

    // Adjointness, force conservation with walls, thread-count determinism.
    let mut t = Table::new(
        "adjointness and determinism (2e4 markers, 32^3; walled: markers up to the walls)",
        &[
            ("kernel", false),
            ("adjoint_periodic", false),
            ("adjoint_walled", false),
            ("force_cons_walled", false),
            ("mismatch_2thr", false),
            ("mismatch_4thr", false),
        ],
    );
    let cases: Vec<([bool; 3], Vec<[f64; 3]>)> = vec![
        (periodic, markers(&mut rng, grid, periodic, 0.0, 20_000)),
        (walled, markers(&mut rng, grid, walled, -0.5, 20_000)),
    ];
    let f: Vec<[f64; 3]> = (0..20_000).map(|_| rng.vec3(-1.0, 1.0)).collect();
    let u: Vec<[f64; 3]> = (0..grid.nodes()).map(|_| rng.vec3(-1.0, 1.0)).collect();
    for k in DeltaKernel::ALL {
        let mut defects = [0.0; 2];
        let mut conservation = 0.0f64;
        let (mut mis2, mut mis4) = (0usize, 0usize);
        for (ci, (per, pos)) in cases.iter().enumerate() {
            let st = stencils(k, grid, *per, pos);
            let mut iu = vec![[0.0; 3]; pos.len()];
            interpolate(&u, &st, &mut iu);
            let mut sf = vec![[0.0; 3]; grid.nodes()];
            spread(&f, &st, &mut sf);
            let l = dot(&iu, &f);
            defects[ci] = (l - dot(&u, &sf)).abs() / l.abs();
            if !per[0] {
                for c in 0..3 {
                    let nodes = csum(sf.iter().map(|v| v[c]));
                    let marks = csum(f.iter().map(|v| v[c]));
                    let scale: f64 = f.iter().map(|v| v[c].abs()).sum();
                    conservation = conservation.max((nodes - marks).abs() / scale);
                }
            }
            let spread_bits = |threads| {
                in_pool(threads, || {
                    let st = stencils(k, grid, *per, pos);
                    let mut sf = vec![[0.0; 3]; grid.nodes()];
                    spread(&f, &st, &mut sf);
                    sf.iter().map(|v| v.map(f64::to_bits)).collect::<Vec<_>>()
                })
            };
            let one = spread_bits(1);
            let count = |other: Vec<[u64; 3]>| {
                one.iter().zip(&other).map(|(a, b)| (0..3).filter(|&c| a[c] != b[c]).count()).sum::<usize>()
            };
            mis2 += count(spread_bits(2));
            mis4 += count(spread_bits(4));
        }
        t.push(vec![kernel_id(k), defects[0], defects[1], conservation, mis2 as f64, mis4 as f64]);
        let why = "inner products compensated; what is left is the operators' own round-off (≤ 64 \
                   terms per marker and per node, random sign): ~1e-15; weights differing \
                   between I and S give ≥ 1e-3";
        out.checks.push(Check::at_most(
            CASE,
            format!("{}_adjoint_defect_periodic", k.name()),
            defects[0],
            1e-13,
            why,
        ));
        out.checks.push(Check::at_most(
            CASE,
            format!("{}_adjoint_defect_walled", k.name()),
            defects[1],
            1e-13,
            why,
        ));
        out.checks.push(Check::at_most(
            CASE,
            format!("{}_force_conservation_walled", k.name()),
            conservation,
            1e-13,
            "renormalised wall stencils sum to 1 within ~1e-15 and the sums are compensated; \
             dropping the cut weights without renormalising loses ~1e-2",
        ));
        let why = "z-slab schedule: the order of the additions to each node is fixed by the input, \
                   not by the threads (proof in slurry::ibm::transfer)";
        out.checks.push(Check::exact(
            CASE,
            format!("{}_spread_mismatches_1_vs_2_threads", k.name()),
            mis2 as f64,
            0.0,
            why,
        ));
        out.checks.push(Check::exact(
            CASE,
            format!("{}_spread_mismatches_1_vs_4_threads", k.name()),
            mis4 as f64,
            0.0,
            why,
        ));
    }
    out.tables.push(t);

    out.tables.push(cost());
    out
}

/// Cost per marker of build, interpolate and spread on 128³ with ≈ 10⁵ markers.
fn cost() -> Table {
    let grid = Grid::new(128, 128, 128);
    let mut rng = Rng(42);
    let mut pos = Vec::with_capacity(111 * 900);
    for _ in 0..111 {
        let c = rng.vec3(0.0, 128.0);
        sphere(c, 6.0, 900, &mut pos);
    }
    let f: Vec<[f64; 3]> = (0..pos.len()).map(|_| rng.vec3(-1e-3, 1e-3)).collect();
    let u: Vec<[f64; 3]> = (0..grid.nodes()).map(|_| rng.vec3(-0.05, 0.05)).collect();
    let mut t = Table::new(
        format!("cost, ns per marker ({} markers on 111 spheres d=12, 128^3 periodic; min of 7)", pos.len()),
        &[("kernel", false), ("threads", false), ("build", false), ("interpolate", false), ("spread", false)],
    );
    let mut field = vec![[0.0; 3]; grid.nodes()];
    let mut iu = vec![[0.0; 3]; pos.len()];
    for k in DeltaKernel::ALL {
        for threads in [1, 2] {
            let (b, i, s) = in_pool(threads, || {
                let mut st = Stencils::new(k);
                let (mut build_s, mut interpolate_s, mut spread_s) = (Vec::new(), Vec::new(), Vec::new());
                for _ in 0..7 {
                    let t0 = Instant::now();
                    st.build(grid, [true; 3], &pos).expect("inside");
                    build_s.push(t0.elapsed().as_secs_f64());
                    let t0 = Instant::now();
                    interpolate(&u, &st, &mut iu);
                    interpolate_s.push(t0.elapsed().as_secs_f64());
                    let t0 = Instant::now();
                    spread(&f, &st, &mut field);
                    spread_s.push(t0.elapsed().as_secs_f64());
                }
                (min(&build_s), min(&interpolate_s), min(&spread_s))
            });
            let per = 1e9 / pos.len() as f64;
            t.push(vec![kernel_id(k), threads as f64, b * per, i * per, s * per]);
        }
    }
    t
}
