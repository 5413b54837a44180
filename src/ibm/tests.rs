//! Properties of the transfer operators: moment conditions of the 3-D weights, exactness on
//! linear fields, force conservation, adjointness, thread-count determinism.

use super::*;
use crate::lattice::Grid;

/// splitmix64: a tiny seeded generator (tests need reproducible, not strong, randomness).
use crate::util::{compensated_sum as csum, SplitMix64 as Rng};

fn dot(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    csum(a.iter().zip(b).flat_map(|(x, y)| (0..3).map(move |k| x[k] * y[k])))
}

/// Markers anywhere in the box `[−½, n − ½]³` (on walled axes) or beyond it (periodic axes).
fn markers(rng: &mut Rng, grid: Grid, periodic: [bool; 3], count: usize) -> Vec<[f64; 3]> {
    (0..count)
        .map(|_| {
            let mut x = [0.0; 3];
            for a in 0..3 {
                let n = grid.dim(a) as f64;
                x[a] = if periodic[a] { rng.uniform(-n, 2.0 * n) } else { rng.uniform(-0.5, n - 0.5) };
            }
            x
        })
        .collect()
}

fn build(kernel: DeltaKernel, grid: Grid, periodic: [bool; 3], pos: &[[f64; 3]]) -> Stencils {
    let mut st = Stencils::new(kernel);
    st.build(grid, periodic, pos).expect("markers inside the box");
    st
}

/// Minimal-image displacement `x − X` on an axis of `n` nodes (periodic) or plain (walled),
/// computed as an integer part and the fraction of `X` so that the measurement adds no
/// rounding of its own at the magnitude of `X`.
fn disp(x: usize, xm: f64, n: usize, periodic: bool) -> f64 {
    let fl = xm.floor();
    let mut k = x as i64 - fl as i64;
    if periodic {
        let n = n as i64;
        k = (k + n / 2).rem_euclid(n) - n / 2;
    }
    k as f64 - (xm - fl)
}

/// Tolerance 1e-14: each 1-D weight carries an absolute error of a few ulps of 1 (the sqrt
/// formulas), the displacements are exact or carry one rounding at the magnitude of the kernel
/// argument (≤ 2); a sum of ≤ 64 products of three such weights stays below ~1e-15.
#[test]
fn partition_of_unity_and_first_moments() {
    let mut rng = Rng(1);
    for periodic in [[true; 3], [false; 3]] {
        let grid = Grid::new(20, 24, 28);
        // Periodic: anywhere (stencils wrap). Walled: at least one support away from the walls.
        let pos: Vec<[f64; 3]> = if periodic[0] {
            markers(&mut rng, grid, periodic, 2000)
        } else {
            (0..2000)
                .map(|_| [rng.uniform(2.5, 16.5), rng.uniform(2.5, 20.5), rng.uniform(2.5, 24.5)])
                .collect()
        };
        for k in DeltaKernel::ALL {
            let st = build(k, grid, periodic, &pos);
            for (m, x) in pos.iter().enumerate() {
                let mut s = 0.0;
                let mut mom = [0.0; 3];
                st.for_each_node(m, |n, w| {
                    let c = grid.coords(n);
                    s += w;
                    for a in 0..3 {
                        mom[a] += disp(c[a], x[a], grid.dim(a), periodic[a]) * w;
                    }
                });
                assert!((s - 1.0).abs() < 1e-14, "{k:?} {x:?}: Σδ − 1 = {}", s - 1.0);
                assert!(mom.iter().all(|v| v.abs() < 1e-14), "{k:?} {x:?}: first moments {mom:?}");
            }
        }
    }
}

/// Next to a wall the renormalised weights still sum to one (force conservation), while the
/// first moment is no longer zero (documented in `stencil`).
#[test]
fn walls_keep_partition_of_unity() {
    let grid = Grid::new(8, 8, 8);
    for k in DeltaKernel::ALL {
        for &z in &[-0.5, -0.25, 0.0, 0.4, 7.0, 7.5] {
            let st = build(k, grid, [true, true, false], &[[3.3, 4.1, z]]);
            let mut s = 0.0;
            st.for_each_node(0, |n, w| {
                assert!(grid.coords(n)[2] < 8);
                s += w;
            });
            assert!((s - 1.0).abs() < 1e-14, "{k:?} z={z}: Σδ = {s}");
        }
    }
}

/// A linear field `u_k(x) = a_k + b_k · x` interpolates exactly (first moments vanish) away from
/// walls. Values are O(100); tolerance 1e-12 = a few ulps of them times the 64-term sum.
#[test]
fn linear_field_interpolates_exactly() {
    let mut rng = Rng(2);
    let grid = Grid::new(16, 20, 24);
    let a = rng.vec3(-1.0, 1.0);
    let b = [rng.vec3(-2.0, 2.0), rng.vec3(-2.0, 2.0), rng.vec3(-2.0, 2.0)];
    let lin = |x: [f64; 3]| -> [f64; 3] {
        std::array::from_fn(|k| a[k] + b[k][0] * x[0] + b[k][1] * x[1] + b[k][2] * x[2])
    };
    let field: Vec<[f64; 3]> = (0..grid.nodes()).map(|n| lin(grid.coords(n).map(|c| c as f64))).collect();
    let pos: Vec<[f64; 3]> =
        (0..3000).map(|_| [rng.uniform(2.5, 12.5), rng.uniform(2.5, 16.5), rng.uniform(2.5, 20.5)]).collect();
    for k in DeltaKernel::ALL {
        for periodic in [[true; 3], [false; 3]] {
            let st = build(k, grid, periodic, &pos);
            let mut out = vec![[0.0; 3]; pos.len()];
            interpolate(&field, &st, &mut out);
            for (x, u) in pos.iter().zip(&out) {
                let e = lin(*x);
                for c in 0..3 {
                    assert!((u[c] - e[c]).abs() < 1e-12, "{k:?} {x:?}: {} vs {}", u[c], e[c]);
                }
            }
        }
    }
}

/// `Σ_n (S F)_n = Σ_m F_m`: periodic with wrap-around, walled with markers up to the walls
/// (renormalised weights), and on a grid too thin for parallel slabs. Tolerance 1e-13 of
/// `Σ|F|`: every marker's weights sum to 1 within ~1e-15, and the two sums add ≤ 1e4 terms.
#[test]
fn spreading_conserves_total_force() {
    let mut rng = Rng(3);
    for (grid, periodic) in [
        (Grid::new(16, 12, 32), [true; 3]),
        (Grid::new(16, 12, 32), [false; 3]),
        (Grid::new(9, 7, 6), [true, false, true]),
    ] {
        let pos = markers(&mut rng, grid, periodic, 5000);
        let f: Vec<[f64; 3]> = (0..pos.len()).map(|_| rng.vec3(-1.0, 1.0)).collect();
        for k in DeltaKernel::ALL {
            let st = build(k, grid, periodic, &pos);
            let mut field = vec![[0.0; 3]; grid.nodes()];
            spread(&f, &st, &mut field);
            for c in 0..3 {
                let total = csum(field.iter().map(|v| v[c]));
                let markers = csum(f.iter().map(|v| v[c]));
                let scale: f64 = f.iter().map(|v| v[c].abs()).sum();
                assert!(
                    (total - markers).abs() < 1e-13 * scale,
                    "{k:?} {grid:?} {periodic:?} component {c}: {total} vs {markers}"
                );
            }
        }
    }
}

/// `⟨I u, F⟩ = ⟨u, S F⟩` for random `u`, `F` in `[−1, 1]`. Relative tolerance 1e-13: the inner
/// products are summed with compensation, so what remains is the operators' own round-off —
/// each `(I u)_m` and `(S F)_n` a sum of ≤ 64 terms of size ≤ 1 with relative error ~1e-16 per
/// addition, random in sign — ~1e-15 relative to the inner product of zero-mean data (measured
/// ≈ 1e-15). Any mismatch of the weights (e.g. renormalised on one side only) gives > 1e-3.
#[test]
fn interpolation_and_spreading_are_adjoint() {
    let mut rng = Rng(4);
    for (grid, periodic) in [
        (Grid::new(24, 20, 32), [true; 3]),
        (Grid::new(24, 20, 32), [false; 3]),
        (Grid::new(5, 1, 7), [true; 3]),
    ] {
        let pos = markers(&mut rng, grid, periodic, 4000);
        let f: Vec<[f64; 3]> = (0..pos.len()).map(|_| rng.vec3(-1.0, 1.0)).collect();
        let u: Vec<[f64; 3]> = (0..grid.nodes()).map(|_| rng.vec3(-1.0, 1.0)).collect();
        for k in DeltaKernel::ALL {
            let st = build(k, grid, periodic, &pos);
            let mut iu = vec![[0.0; 3]; pos.len()];
            interpolate(&u, &st, &mut iu);
            let mut sf = vec![[0.0; 3]; grid.nodes()];
            spread(&f, &st, &mut sf);
            let (l, r) = (dot(&iu, &f), dot(&u, &sf));
            let defect = (l - r).abs() / l.abs();
            assert!(
                defect < 1e-13,
                "{k:?} {grid:?} {periodic:?}: ⟨Iu,F⟩ = {l}, ⟨u,SF⟩ = {r}, defect {defect:e}"
            );
        }
    }
}

/// The slab schedule against a plain serial loop in marker order: the same sums, added in
/// another order (so equal to round-off, not bitwise); catches a marker spread twice or never.
#[test]
fn slab_schedule_matches_plain_loop() {
    let mut rng = Rng(5);
    let grid = Grid::new(10, 10, 30);
    for periodic in [[true; 3], [false; 3]] {
        let pos = markers(&mut rng, grid, periodic, 3000);
        let f: Vec<[f64; 3]> = (0..pos.len()).map(|_| rng.vec3(-1.0, 1.0)).collect();
        for k in DeltaKernel::ALL {
            let st = build(k, grid, periodic, &pos);
            assert!(st.slabs() >= 4);
            let mut fast = vec![[0.0; 3]; grid.nodes()];
            spread(&f, &st, &mut fast);
            let mut plain = vec![[0.0; 3]; grid.nodes()];
            for m in 0..pos.len() {
                st.for_each_node(m, |n, w| (0..3).for_each(|c| plain[n][c] += w * f[m][c]));
            }
            let worst = fast
                .iter()
                .zip(&plain)
                .flat_map(|(a, b)| (0..3).map(move |c| (a[c] - b[c]).abs()))
                .fold(0.0, f64::max);
            assert!(worst < 1e-12, "{k:?} {periodic:?}: {worst:e}");
        }
    }
}

fn in_pool<R: Send>(threads: usize, f: impl FnOnce() -> R + Send) -> R {
    rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("thread pool").install(f)
}

fn bits(v: &[[f64; 3]]) -> Vec<[u64; 3]> {
    v.iter().map(|x| x.map(f64::to_bits)).collect()
}

/// Spreading and interpolation give the same bits with 1, 2, 3 and 5 threads.
#[test]
fn bitwise_identical_for_any_thread_count() {
    let mut rng = Rng(6);
    for (grid, periodic) in [
        (Grid::new(12, 10, 40), [true; 3]),
        (Grid::new(12, 10, 41), [false; 3]),
        (Grid::new(12, 10, 26), [true, true, false]),
    ] {
        let pos = markers(&mut rng, grid, periodic, 6000);
        let f: Vec<[f64; 3]> = (0..pos.len()).map(|_| rng.vec3(-1.0, 1.0)).collect();
        let u: Vec<[f64; 3]> = (0..grid.nodes()).map(|_| rng.vec3(-1.0, 1.0)).collect();
        for k in DeltaKernel::ALL {
            let run = |threads| {
                in_pool(threads, || {
                    let st = build(k, grid, periodic, &pos);
                    let mut field = vec![[0.0; 3]; grid.nodes()];
                    spread(&f, &st, &mut field);
                    let mut out = vec![[0.0; 3]; pos.len()];
                    interpolate(&u, &st, &mut out);
                    (bits(&field), bits(&out), st.slabs())
                })
            };
            let one = run(1);
            assert!(one.2 >= 4, "parallel path exercised");
            for threads in [2, 3, 5] {
                assert!(run(threads) == one, "{k:?} {grid:?} {periodic:?}: {threads} threads differ");
            }
        }
    }
}

/// Marker order is part of the input: a permutation changes only round-off (the additions to
/// a shared node are reordered), which is why the caller must keep it fixed.
#[test]
fn marker_permutation_changes_only_round_off() {
    let mut rng = Rng(7);
    let grid = Grid::new(12, 12, 24);
    let pos = markers(&mut rng, grid, [true; 3], 3000);
    let f: Vec<[f64; 3]> = (0..pos.len()).map(|_| rng.vec3(-1.0, 1.0)).collect();
    let perm: Vec<usize> = (0..pos.len()).rev().collect();
    let (pp, fp): (Vec<_>, Vec<_>) = perm.iter().map(|&i| (pos[i], f[i])).unzip();
    let st = build(DeltaKernel::Roma3, grid, [true; 3], &pos);
    let stp = build(DeltaKernel::Roma3, grid, [true; 3], &pp);
    let (mut a, mut b) = (vec![[0.0; 3]; grid.nodes()], vec![[0.0; 3]; grid.nodes()]);
    spread(&f, &st, &mut a);
    spread(&fp, &stp, &mut b);
    let worst =
        a.iter().zip(&b).flat_map(|(x, y)| (0..3).map(move |c| (x[c] - y[c]).abs())).fold(0.0, f64::max);
    assert!(worst < 1e-13, "{worst:e}");
}

/// The closure-backed field reads the same values as the slice.
#[test]
fn fn_field_equals_slice() {
    let mut rng = Rng(8);
    let grid = Grid::new(8, 8, 16);
    let u: Vec<[f64; 3]> = (0..grid.nodes()).map(|_| rng.vec3(-1.0, 1.0)).collect();
    let pos = markers(&mut rng, grid, [true; 3], 500);
    let st = build(DeltaKernel::Peskin4, grid, [true; 3], &pos);
    let (mut a, mut b) = (vec![[0.0; 3]; pos.len()], vec![[0.0; 3]; pos.len()]);
    interpolate(&u[..], &st, &mut a);
    interpolate(&FnField { nodes: grid.nodes(), f: |n: usize| u[n] }, &st, &mut b);
    assert_eq!(bits(&a), bits(&b));
}

/// `for_each_row_in` (the addresses the interpolation and the spreading prefetch) names the first node of each
/// x-row of `for_each_node_in`, row by row, for every kernel, on periodic and walled axes
/// (clipped stencils), in a padded layout.
#[test]
fn rows_start_where_the_stencil_rows_start() {
    let mut rng = Rng(11);
    let grid = Grid::new(9, 7, 16);
    let layout = crate::lattice::NodeLayout { base: 5, sy: 11, sz: 11 * 9 };
    for kernel in [DeltaKernel::Linear, DeltaKernel::Roma3, DeltaKernel::Peskin4] {
        for periodic in [[true; 3], [false; 3]] {
            let pos = markers(&mut rng, grid, periodic, 300);
            let st = build(kernel, grid, periodic, &pos);
            for m in 0..pos.len() {
                let mut rows = Vec::new();
                st.for_each_row_in(layout, m, |n| rows.push(n));
                let mut firsts = Vec::new();
                let mut last_row = None;
                st.for_each_node_in(layout, m, |n, _| {
                    // A new x-row starts wherever the (y, z) row base changes.
                    let row = (n - layout.base) / layout.sy;
                    if last_row != Some(row) {
                        firsts.push(n);
                        last_row = Some(row);
                    }
                });
                assert_eq!(rows, firsts, "{kernel:?}, periodic {periodic:?}, marker {m}");
            }
        }
    }
}

/// `for_each_xrow_in` (the spreading's rows) gives the nodes of `for_each_node_in` in the same
/// order with bitwise the same weights whenever a marker's x-nodes are consecutive, and
/// declines (calling nothing) at a periodic seam, where they wrap; for every kernel, on
/// periodic and walled axes (clipped stencils), in a padded layout.
#[test]
fn x_rows_are_the_stencil_nodes_in_order() {
    let mut rng = Rng(17);
    let grid = Grid::new(9, 7, 16);
    let layout = crate::lattice::NodeLayout { base: 5, sy: 11, sz: 11 * 9 };
    let (mut by_rows, mut declined) = (0, 0);
    for kernel in [DeltaKernel::Linear, DeltaKernel::Roma3, DeltaKernel::Peskin4] {
        for periodic in [[true; 3], [false; 3]] {
            let pos = markers(&mut rng, grid, periodic, 300);
            let st = build(kernel, grid, periodic, &pos);
            for m in 0..pos.len() {
                let mut nodes = Vec::new();
                st.for_each_node_in(layout, m, |n, w| nodes.push((n, w.to_bits())));
                let mut rows = Vec::new();
                let done = st.for_each_xrow_in(layout, m, |n, w| {
                    rows.extend(w.iter().enumerate().map(|(k, wk)| (n + k, wk.to_bits())));
                });
                if done {
                    by_rows += 1;
                    assert_eq!(rows, nodes, "{kernel:?}, periodic {periodic:?}, marker {m}");
                } else {
                    declined += 1;
                    assert!(rows.is_empty() && periodic[0], "{kernel:?}, marker {m}: declined off a seam");
                    let xs: Vec<usize> = nodes.iter().map(|&(n, _)| (n - layout.base) % layout.sy).collect();
                    assert!(xs.windows(2).any(|p| p[1] != p[0] && p[1] != p[0] + 1), "marker {m}: {xs:?}");
                }
            }
        }
    }
    assert!(by_rows > 1000 && declined > 10, "{by_rows} by rows, {declined} declined");
}
