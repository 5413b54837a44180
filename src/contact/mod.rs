//! Contacts between rigid bodies and against the box walls: the collision model of Derksen
//! (2020, Table 1; the same as Derksen 2019) between **surface markers**, its fast evaluation
//! (broad phase, narrow phase, parallel and deterministic), a brute-force [`oracle`], and the
//! **sub-cycling** of the bodies over one fluid time step. Knows only [`crate::rigid`]: bodies
//! come in as [`RigidBody`](crate::rigid::RigidBody) slices with their body-frame
//! [`Marker`](crate::rigid::Marker) sets (the ones the immersed boundary method uses), loads go
//! out as [`ContactLoad`]s. Lattice units throughout.
//!
//! # The model (Table 1)
//!
//! For a marker `i` of body `a` (world position `x_i`, outward unit normal `n_i`, velocity
//! `u_i = v_a + ω_a × (x_i − x_a)`) and a marker `j` of another body `b`:
//!
//! ```text
//! n̂   = (n_i − n_j)/|n_i − n_j|        contact normal, from i toward j
//! δ   = (x_j − x_i)·n̂                  normal distance (negative: overlap)
//! δ_λ = |(x_j − x_i) − δ n̂|            tangential distance
//! w   = (λ − δ_λ)/λ  if δ_λ < λ,  else 0 (no interaction)
//!
//! F_el  on i = −k (δ0 − δ) w n̂                                   if δ < δ0
//! F_lub on i = (kⁿ Δuⁿ + kᵗ Δuᵗ)(1/δ* − 1/δ_d) w                 if δ* < δ_d
//!              δ* = max(δ, δ_sat),  Δu = u_j − u_i,  Δuⁿ = (Δu·n̂) n̂,  Δuᵗ = Δu − Δuⁿ
//! ```
//!
//! with Table 1's `k = 5.0, δ0 = 0.5, λ = 0.5, kⁿ = 5.0, δ_d = 1.0, δ_sat = 0.2, kᵗ = 0.5`
//! ([`ContactParams::default`]; switches `elastic`, `lubrication` turn the parts off). Pairs
//! whose normals do not face each other are skipped: `n_i·n_j > 0` or `|n_i − n_j| < 1e-12`.
//!
//! **Sign (a correction of the printed table).** The paper prints the weight as
//! `(δ_λ − λ)/λ`, which is negative for every interacting pair (`δ_λ < λ`). Its direction
//! `(n_j − n_i)/|n_j − n_i| = −n̂` points from `j` toward `i`, i.e. away from `j`: with a positive
//! weight the printed elastic force on `i` pushes it away from `j` (repulsive, as the text
//! says: it "prevents them from overlapping"); with the printed negative weight it pulls `i`
//! toward `j`. The weight used here is `w = (λ − δ_λ)/λ ≥ 0`, so `F_el` on `i` is
//! `k(δ0 − δ) w (−n̂) = −k(δ0 − δ) w n̂`. For the lubrication the table leaves the sign of
//! `Δu` open; with `w ≥ 0` and `Δu = u_j − u_i` the force resists the relative motion (its
//! power on the pair, `F·(u_i − u_j) = −(kⁿ|Δuⁿ|² + kᵗ|Δuᵗ|²)(1/δ* − 1/δ_d) w`, is never
//! positive) — the printed form with its negative weight and `Δu = u_i − u_j`.
//!
//! **Newton's third law, exactly.** Each pair's force is computed once and applied as `+F` to
//! `i` and `−F` to `j` (the formula is antisymmetric: swapping `i` and `j` flips `n̂` and `Δu`
//! and keeps `δ`, `δ_λ`, `w`), each at its own marker: the torque on a body is
//! `Σ (x_i − x_body) × F_i` about its centre of mass. The total force on all bodies plus the
//! wall reaction ([`Contacts::wall_reaction`]) vanishes to round-off (tested). Angular momentum
//! is not conserved exactly: the marker forces are not central (a pair's force is along `n̂`,
//! or along `Δu`, not along `x_j − x_i`).
//!
//! **Walls.** A box wall at coordinate `p` on axis `a` ([`Walls`]: half-way bounce-back walls
//! at `−0.5` and `n − 0.5`) acts on a marker of a free body whose normal faces it
//! (`n_i·n̂ > 0`, `n̂` the wall's outward normal seen from the fluid, `−e_z` for the floor) with
//! `δ` = the distance from the marker to the plane, `δ_λ = 0` (`w = 1`), the wall at rest: the
//! same formulas, elastic part along the wall normal. (A flat wall thus has one partner per
//! marker with `w = 1`, where a flat particle face has `Σ_j w ≈ πλ²/(3h²) ≈ 0.53` per marker
//! at spacing `h = 0.7`, up to ≈ 1 if the two marker lattices are aligned.)
//!
//! **Body kinds.** Fixed, prescribed and free bodies all take part; pairs of two non-free
//! bodies are skipped, and walls act on free bodies only. A fixed or prescribed body is
//! infinitely heavy: [`Contacts::compute`] returns its contact load (for an impeller, the
//! paper's **solids torque**), and the caller does not apply it.
//!
//! **Which pairs.** Only marker pairs closer than the **reach**
//! `√(cutoff² + λ²)`, `cutoff = max(δ0, δ_d)` (1.118 with Table 1), are examined: every pair with
//! `|δ| < cutoff` and `δ_λ < λ` is within it. A pair overlapping deeper than about the reach
//! (`δ < −√(reach² − δ_λ²)`) is not seen; by then the surfaces have crossed by more than a
//! marker spacing and the marker model has no meaningful answer anyway. The fast path and the
//! oracle use exactly this criterion (`|x_j − x_i|² < reach²`).
//!
//! # Evaluation ([`Contacts::compute`])
//!
//! The narrow phase is not run at every evaluation: it builds a **marker-pair list with a
//! skin** (module `list`, a Verlet list), which later evaluations reuse while every body has
//! moved by less than half the skin ([`DEFAULT_SKIN`]) since the build — across the contact
//! sub-steps and across fluid steps.
//!
//! 1. **Broad phase** (at a rebuild; module `broad`). Bounding spheres (centre of mass,
//!    radius = largest marker distance, computed once per body) in a uniform cell list of edge
//!    `2 r_max + range`, `range = reach + skin`; candidate pairs `(a, b)`, `a < b`, with
//!    `|c_a − c_b| < r_a + r_b + range` and not both non-free, sorted lexicographically. Bodies
//!    much larger than the typical one (radius above 4 × the median: an impeller among
//!    particles) stay out of the cell list and are tested against every body. A refresh tests
//!    only the bodies that moved beyond half the skin against every body.
//! 2. **Narrow phase, per candidate pair** (at a rebuild, in parallel). Early out if one body's
//!    bounding sphere is farther than `range` from the other's marker box or surface. Each
//!    body's markers are grouped once into static **patches** (body-frame cubes of edge 2,
//!    each with the bounding sphere of its markers). The markers of `a` that may lie within
//!    `range` of a marker of `b` are those in patches meeting `b`'s bounding sphere grown by
//!    `range`, then (per patch, then per marker) within `range` of the box of `b`'s markers and
//!    within `range + tol_b` of `b`'s surface, `|sd_b| < range + tol_b` (`sd_b` the shape's
//!    signed distance, a true Euclidean distance and so 1-Lipschitz; `tol_b` the largest
//!    `|sd_b|` of `b`'s own markers). Every test is a lower bound with a margin of 1e-6, so no
//!    pair within range is lost. `b`'s candidates are binned into cubes of edge `≥ range`, each
//!    marker of `a` scans the 27 neighbouring bins, and a pair within `range` is listed if it
//!    can still interact before the next rebuild (facing normals reachable, tangential
//!    distance below `λ` reachable: bounds in module `list`).
//! 3. **Walls** (at a rebuild, per free body near a wall): patches within `cutoff + skin/2` of
//!    a wall, then their markers.
//! 4. **Evaluation from the list** (every sub-step, in parallel over chunks of body pairs):
//!    each pair's two sides of markers are transformed to the world frame, and its listed
//!    marker pairs closer than `reach` go through the force law in batches of 64
//!    (`force::PairBatch`: without branches, 4 lanes at a time with AVX2, each lane the scalar
//!    law's operations in its order, so bitwise the same hits); the interacting ones are summed
//!    in list order.
//! 5. **Determinism** (module `slots`). Each pair's listed marker pairs are sorted by
//!    `(i, j)` and summed into a per-pair slot (force and torque on both partners); the slots
//!    are then added into the per-body totals serially in pair order, then the wall slots in
//!    body order. The result is bitwise the same for any number of threads, and bitwise
//!    equal to the brute-force [`oracle`] whether the list was just built or reused
//!    (`tests/contact_oracle.rs`).
//! 6. **No allocation in steady state.** Every buffer (poses, cell list, pairs, list, slots,
//!    per-thread scratch) lives in [`Contacts`] and is cleared and refilled;
//!    [`Contacts::buffer_capacity`] exposes the total capacity (constant from one call to the
//!    next once warm; with several threads, each thread's scratch grows until that thread has
//!    met the largest pair).
//!
//! # Sub-cycling ([`Contacts::advance`])
//!
//! Contacts are stiffer than the fluid step allows: the bodies are advanced over one fluid
//! step `Δt = 1` in `n_sub` sub-steps `h = 1/n_sub`, contacts recomputed each sub-step at the
//! mid-sub-step pose predicted from the current velocities, external loads (hydrodynamic force
//! and torque, net weight; from the bodies' accumulators at level `n`) held at their
//! linear-in-time extrapolation, each free body stepped with constant-load semantics
//! ([`Contacts::advance`] gives the scheme and why). With `RigidBody::step`
//! (`v' = v + h F/m`, `x' = x + h(v + v')/2`) this is position Verlet for the spring
//! (symplectic: elastic-only normal impacts return their kinetic energy to 0.4 %) and explicit
//! Euler for the lubrication damping.
//!
//! ## Stability analysis and the default `n_sub`
//!
//! **Damping.** The stiffest term is the lubrication at saturation (`δ ≤ δ_sat`): per marker
//! pair `c₁ = kⁿ(1/δ_sat − 1/δ_d) = 20` (normal; tangential `kᵗ(…) = 2`). A contact of area `A`
//! has `A/h²` markers (`h = 0.7`, `h² = 0.49`) each with `Σ_j w` ≈ 0.53 partners (random
//! alignment) up to ≈ 1 (aligned lattices), or exactly 1 against a wall, so a flat face is the
//! worst: a cap of `d = 12` has 231 cap and 54 rim markers, `c ≈ 20 × 271 ≈ 5400`. For the
//! relative normal velocity `u` of two bodies (reduced mass `m_red`; a body against a wall or
//! a prescribed body: its mass), explicit Euler gives per sub-step `u ← (1 − b) u`,
//! `b = c h/m_red`: **stable for `b < 2`, monotone (no reversal) for `b ≤ 1`**. Measured with
//! this code (`c = −∂F/∂u` at saturation; `γ = 1.25`, `ℓ = d`):
//!
//! | contact (saturated)          | `d = 6`: `c`, `m_red`, `c/m_red` | `d = 12`: `c`, `m_red`, `c/m_red` |
//! |------------------------------|----------------------------------|-----------------------------------|
//! | cap on cap, markers aligned  | 1134, 106, **10.7**              | 4980, 848, **5.87**               |
//! | cap on the wall              | 1360, 212, 6.41                  | 5420, 1696, 3.20                  |
//! | mantle on the wall (touching)| 884, 212, 4.17                   | 2222, 1696, 1.31                  |
//! | mantle on mantle, parallel   | 301, 106, 2.84                   | 1418, 848, 1.67                   |
//! | sphere on the wall           | 320, 141, 2.26                   | 629, 1131, 0.56                   |
//! | sphere on sphere             | 78, 71, 1.11                     | 160, 565, 0.28                    |
//! | rocking of a cap on the wall | `c_rot/I` = 4.49                 | `c_rot/I` = 2.06                  |
//!
//! `c/m_red ∝ 1/d` for flat contacts (area `∝ d²`, mass `∝ d³`). With **`n_sub = 8`**
//! ([`DEFAULT_SUBSTEPS`]): the stiffest single contact has `b = 0.73` at the paper's scale
//! `d = 12` (monotone) and `b = 1.34` at half scale `d = 6` (stable; the relative velocity
//! overshoots to −0.34 `u` per sub-step and is damped by 1.7e-4 per fluid step); `n_sub = 4`
//! would make the aligned cap–cap contact at `d = 6` unstable (`b = 2.67`, growth × 7.9 per fluid
//! step). The verification case `contacts_dry` measures these amplification factors and matches
//! `(1 − b)^{n_sub}` to 1e-9. Loads add up when several saturated contacts act on one body: a
//! `d = 12` cylinder pinched flat between the wall and a flat (infinitely heavy) blade has
//! `b = 2 × 3.2/8 = 0.80`, at `d = 6` 1.6 (stable); a chain of three or more saturated flat
//! contacts (highest mode twice the pair rate) reaches `b = 1.47` at `d = 12` (stable) but 2.7
//! at `d = 6` (unstable: such a chain at half scale needs `n_sub = 16`). Saturated flat
//! contacts are rare in practice: the lubrication stops a flat impact far from `δ_sat` (dry
//! impacts at the tip speed 0.104 stop at `δ` = 0.67 cap on cap and 0.58 cap on wall at
//! `d = 12`), and at rest under the spring (`δ ≈ δ0 = 0.5`) `c₁ = 5`, four times less.
//!
//! **Spring.** Per pair `k w ≤ 5`; the stiffest contact (aligned caps, `d = 6`) has
//! `k_tot = 303`, `ω = √(k_tot/m_red) = 1.69`; cap on the wall at `d = 12`: 1355, `ω = 0.89`.
//! Accuracy of a resolved oscillation asks `h < 0.2 · 2π/ω` (≥ 5 sub-steps per period):
//! `h < 0.74` at `d = 6`. At `n_sub = 8`, `ω h ≤ 0.21` (30 sub-steps per period).
//!
//! So `n_sub = 8` is the smallest power of two (sub-step times exact) for which every single
//! saturated contact is monotone at the paper's scale and stable at half scale.
//!
//! ## Lubrication limiter (opt-in: [`ContactParams::lubrication_limiter`])
//!
//! To run with fewer sub-steps, the lubrication of each body pair can be limited to the range
//! where explicit Euler is stable. Per sub-step of length `h`, every free body gets a bound of
//! its damping rate over all its lubricated pairs and wall contacts,
//!
//! ```text
//! ρ_b = Σ (cⁿ + cᵗ)/m_b + Σ [cⁿ (r × n̂)ᵀ I_b⁻¹ (r × n̂) + cᵗ |r|²/I_min,b]
//! ```
//!
//! (`cⁿ, cᵗ` the pairs' normal and tangential coefficients, `r` their lever arms; `ρ = 0` for
//! a fixed or prescribed body, which is infinitely heavy), and the lubrication load of pair
//! `(a, b)` is scaled by `s = min(1, 0.9/(h (ρ_a + ρ_b)))` (a wall contact: `ρ_a = 0`). Below
//! the limit (`h (ρ_a + ρ_b) ≤ 0.9`) it is Table 1's law, bitwise. Each pair still applies
//! `+F` and `−F`: momentum is conserved as before. An isolated pair's relative velocity
//! changes per sub-step by `1 − b s` with `b = h c μ ≤ h (ρ_a + ρ_b)` (`μ` the pair's
//! mobility), so `1 − b s ≥ 0.1`: never reversed, whatever `h`; for a body with several
//! contacts, Gershgorin's bound of the damping operator (a weighted graph Laplacian in the
//! mobility metric) is `2 × 0.9 < 2`: stable. The limiter takes away dissipation only where
//! the explicit law would overshoot; where it acts, it damps at the stability limit, so a
//! stiff mode that physically stops within a sub-step stops within a few.
//!
//! **Measured** (pbt-ld2 at s = 1/4, the dry bed at 50 × gravity against a linear drag, 822
//! cylinders; `contacts_dry` checks the single contacts): explicit `n_sub = 8` settles in
//! 1154 steps to a mean centre height of 9.94; with the limiter, `n_sub = 8` 1198 steps, 9.86
//! (the limiter rarely acts); `n_sub = 4` 1864 steps, 9.49; `n_sub = 2` does not settle within
//! 2000 steps (mean speed 4.8e-3 against the stop at 2.5e-3: the springs of the bed jitter,
//! under-damped). In the coupled step after the ramp (`slurry bench --coupled --scales 0.25
//! --cases pbt-ld2 --warmup 1100 --steps 40`, 2 threads, one run; fluid-only step
//! 1.9 ms), contacts cost 19.6 ms per step at explicit `n_sub = 8` (step 36.9 ms), and with
//! the limiter 22.1 ms at 8 (38.9; the split sums cost 13 %), 12.8 ms at 4 (30.8), 7.3 ms
//! at 2 (25.0) and 4.2 ms at 1 (20.6). The
//! default stays the explicit law at `n_sub = 8`: the limiter keeps a run alive where a
//! rare stiff chain would blow up, but it is not yet shown to leave the coupled results
//! unchanged at fewer sub-steps.
//!
//! ## Lubrication sub-steps (opt-in: [`ContactParams::lubrication_substeps`] `= m > 1`)
//!
//! The damping is the stiff part (rates 16–22 per fluid step in the dense beds at s = 1/4,
//! `slurry bench --coupled`), the spring is not (rates ≤ 4), yet every sub-step evaluates both
//! from the marker pairs. Table 1's lubrication is linear in the relative velocity, so an
//! evaluation can hand it on as a linear map of the bodies' velocities (module `operator`): per
//! interacting body pair `(a, b)` three 6 × 6 blocks with `load_a = K_ab V_b − K_aa V_a`,
//! `load_b = K_abᵀ V_a − K_bb V_b` (`V = (v, ω)`), summed over the pair's marker pairs with the
//! evaluation's normals, gaps, weights and lever arms, and per body one block against the
//! walls. With `m > 1` each contact sub-step of length `h` is split into `m` lubrication
//! sub-steps of `h/m`: the elastic load of the evaluation (at the mid-sub-step pose) is held,
//! the lubrication is recomputed from the bodies' current velocities through the frozen map
//! (a prescribed body's at the lubrication sub-step's midpoint), the external load is
//! extrapolated to that midpoint as before, and every body steps by `h/m`. The reported load is
//! the elastic part plus the lubrication averaged over the lubrication sub-steps.
//!
//! What it keeps: at the evaluation's velocities the map gives the law's lubrication to
//! round-off (`operator` tests); `K_aa`, `K_bb` are symmetric positive semi-definite and a
//! pair's power is `−Δuᵀ D Δu ≤ 0`: no energy is created; `+F`/`−F` per pair (momentum to
//! round-off). The damping's stability is the explicit law's at the step `h/m`: saturated
//! contacts decay by `(1 − c h/(m m_red))^{n_sub m}` exactly (`contacts_dry`). What it changes:
//! the lubrication's geometry is frozen and the elastic force held over `h` instead of being
//! re-evaluated every `h/m`. With `n_sub = 2`, `m = 4` (the default's 8 damping steps) the
//! collisions of `contacts_dry` change their restitution by at most 2.0e-4 and their closest
//! approach by at most 1.0e-3, less than the default's own spread over 4 … 32 sub-steps.
//!
//! **Cost** (`slurry bench --coupled`, s = 1/4, 2 threads, from run checkpoints, one window):
//! pbt-ld2 at steady state, contacts 15.8 ms per fluid step at the default against 10.8 ms
//! at `2 × 4` (step 46.6 → 42.1–45.0 ms); pbt-ld1 after 33 revolutions (1644 cylinders, most
//! in the bed), contacts 35.5 → 18.3 ms, step 69.7 → 47.2 ms; at s = 1/2 from the six beds
//! the contacts halve and the step is 1.1–1.3 times faster
//! (`benches/results/2026-11-27-coupled-s0.5-scheme-default.json`, `-lub24.json`).
//! **Not the default**: two paired continuations of steady runs at s = 1/4 put ⟨z_p⟩/H lower
//! by 0.003–0.004 (pbt-ld2) and 0.006–0.0075 (disk-ld1), beyond the spread of two
//! realisations, with the power numbers unchanged within their noise (reproduce/JOURNAL.md,
//! "Lubrication sub-steps").
//!
//! ## Implicit damping (opt-in: [`ContactParams::damping`] `= Damping::Implicit`)
//!
//! **Why backward Euler on the damping.** The stiffness that forces 8 explicit sub-steps is
//! the lubrication's, not the spring's: the stiffest body's damping rate is 13–18 per fluid
//! step in the dense beds at s = 1/4, its spring rate 1.5–3.4. Table 1's damping is linear in
//! the bodies' velocities for a frozen geometry (module `operator`), and its matrix is
//! symmetric positive semi-definite, so backward Euler costs one sparse symmetric
//! positive-definite solve and is unconditionally stable and monotone: a saturated contact's
//! relative velocity is multiplied by `1/(1 + b)` per sub-step (`b = c h/m_red`) instead of
//! `1 − b`, never reversed and never amplified, whatever `h` (verification case
//! `implicit_damping`: at one sub-step, `b` = 10.7 and 19, explicit `|g|` = 9.7 and 18,
//! implicit `g` = `1/(1 + b)` to 1e-6). Table 1's forces are unchanged; only the velocities at
//! which the damping is evaluated move from the sub-step's start to its end.
//!
//! **Why the spring stays explicit.** The elastic force is not linear in the velocities and not
//! the gradient of a potential (its `w` and `n̂` change along a sliding path), an implicit
//! treatment would need Newton iterations over marker pairs that switch on and off; its rate is
//! low (`ω ≤ 3.4` per fluid step), and position Verlet (drift–kick–drift, as before) is stable
//! for `ω h < 2` and symplectic.
//!
//! **The scheme.** Per sub-step of length `h`: the contacts are evaluated at the mid-sub-step
//! pose (drift by `h/2`, as the explicit scheme), giving the elastic loads and, per interacting
//! body pair and per body against the walls, the damping's 6 × 6 operators with the gap-
//! dependent coefficient `(1/δ* − 1/δ_d) w` (`δ* = max(δ, δ_sat)`) of that evaluation. With
//! `V = (v, ω)` per free body, `M = diag(m I, I_world)` and `C` the damping matrix (per pair:
//! `C_aa += K_aa`, `C_bb += K_bb`, `C_ab = −K_ab`, `C_ba = −K_abᵀ`; walls: `C_aa += W_a`), the
//! velocities at the sub-step's end solve
//!
//! ```text
//! (M/h + C) V' = M V/h + F_ext + F_el + K_kin
//! ```
//!
//! (`K_kin`: the terms of fixed and prescribed partners, their velocity given at the
//! sub-step's midpoint: an impeller is kinematic). Only free bodies with a lubricated contact
//! are unknowns. Each free body then steps by `h` (kick, drift) under `F_ext + F_el` plus the
//! damping loads at `V'` from the same operators, so that its new velocity is `V'` (the
//! rotation's gyroscopic term stays explicit) and each pair still applies `+F` and `−F`
//! (momentum to round-off; the reported loads, the solids torque included, are those applied).
//! The system is assembled serially in list order and solved serially (module `implicit`):
//! bitwise the same for any number of threads. The solver ([`ImplicitSolver`]): block-Jacobi
//! preconditioned conjugate gradients to a relative residual of 1e-12 (default), or faer's sparse
//! Cholesky factorisation. Measured on the densest bed at half scale (`examples/contact_cost`,
//! 1644 cylinders `ℓ/d = 1`, `d = 6`, all in the solve; 2 threads, machine shared): the
//! Cholesky factorisation (symbolic and numeric at each sub-step, the pattern changing with the
//! contacts) costs 70 ms per solve, the conjugate gradients 4.5 ms in 16 iterations: `M/h`
//! keeps the system well conditioned (`1 + h·rate`, the rates ≤ 20), so a few iterations
//! suffice, and they need no fill-in. One fluid step's contacts on that bed at rest: explicit,
//! 8 sub-steps, 100.9 ms; implicit, 2 sub-steps, 59.7 ms (of which 5.8 ms assembly and solve; an
//! evaluation with operators costs about twice one without: the 6 × 6 moments per marker pair).
//!
//! **Accuracy and sub-steps.** The scheme is first order in `h` (backward Euler), as the
//! explicit one, and where both are stable their errors are alike. Measured (`implicit_damping`,
//! a sphere `d = 6` driven onto the floor against the damping and the spring, 60 fluid steps,
//! against the explicit scheme Richardson-extrapolated from 32 and 64 sub-steps): the largest
//! gap error at `n_sub = 1, 2, 4, 8` is 5.65e-3, 2.84e-3, 1.43e-3, 7.15e-4 (explicit: 5.80e-3,
//! 2.88e-3, 1.44e-3, 7.16e-4), the velocity error (over the impact speed) 1.34e-2 … 1.74e-3;
//! observed order 0.99. Over `contacts_dry`'s collisions at `d = 6` the closest approach moves
//! against the explicit default (8 sub-steps) by at most 3.4e-2, 2.0e-2, 1.2e-2, 8.2e-3 at
//! `n_sub = 1, 2, 4, 8` (explicit 4: 4.2e-3, explicit 16: 2.1e-3), the restitution by
//! 1.8e-2 … 3.9e-3. So the implicit scheme buys stability, not accuracy: at 2 sub-steps it is as
//! accurate as an explicit scheme at 2 sub-steps would be if that were stable. With the damping
//! implicit, the sub-step count is set by the spring: [`IMPLICIT_SUBSTEPS`] = 2 gives
//! `ω h ≤ 1.7` at the beds' largest spring rate (stable, `< 2`); 4 halves the errors above at
//! twice the cost. It is not the default: the decision needs the 30-revolution comparisons of
//! ⟨z_p⟩/H against the explicit scheme.
//!
//! # Known deviations of the model (measured by `contacts_dry`)
//!
//! - With Table 1's parameters, point and edge impacts of `d = 12` bodies come closer than
//!   `δ_sat`: a cylinder hitting the wall rim first comes to 0.154 of it at 0.05 and 0.035 at
//!   0.075, and at the tip speed 0.104 the rim crosses the wall plane by 0.081; spheres come to
//!   0.164 (0.075) and 0.086 (0.104) of each other head-on. Converged in `n_sub`: a property of
//!   the parameters (kinetic energy `∝ d³`, contact area near a point or an edge `∝ d`). Flat
//!   and line contacts stay above 0.37; at `d = 6` every impact stays above 0.25.
//! - The elastic force is not the gradient of a potential (`w` and `n̂` change along a sliding
//!   path: as marker pairs slide past each other, `½ k (δ0 − δ)² w` appears and vanishes
//!   without the force doing that work), so oblique elastic-only impacts change the kinetic
//!   energy: sphere pairs at 30° lose 3–17 % at `d = 6` and change it by −0.4 … +1.6 % at
//!   `d = 12` (impact speeds 0.005–0.104), the same to 1e-4 for 4 … 32 sub-steps. Normal
//!   impacts conserve it to 0.4 %.
//!   With lubrication, `E = KE + Σ ½ k (δ0 − δ)² w` never exceeds its initial value, but single
//!   sub-steps may raise it (by up to 8.5e-4 of the initial energy, erratically in `n_sub`):
//!   pairs switch on with a finite force when `n_i·n_j` crosses 0.
//!
//! # Cost
//!
//! One fluid step's contacts (8 sub-steps, 2 threads) of the paper's densest bed at half
//! scale (1644 cylinders `ℓ/d = 1`, `d = 6`, a dry bed at rest; `examples/contact_cost`):
//! 152 123 interacting marker pairs and 33 343 wall contacts per evaluation.
//!
//! | evaluation | listed marker pairs | ms per fluid step |
//! |---|---|---|
//! | list, range `reach + 0.5` only | 2 054 385 | 377.7 |
//! | + tangential and facing filter, skin 0.5 | 1 409 332 | 245.6 |
//! | + skin 0.3 | 720 612 | 188.4 |
//! | + sides transformed per pair (no world table; the default) | 720 612 | 103.7 |
//!
//! The rest is the force law and the distance tests of the listed pairs. A narrow phase at
//! every sub-step, without the list, costs about 650 ns per interacting pair (2.13 s per fluid
//! step for the same bed at full scale).

mod broad;
mod contacts;
mod force;
mod grid;
mod implicit;
mod list;
mod operator;
pub mod oracle;
mod params;
mod patches;
mod slots;
mod subcycle;

pub use contacts::Contacts;
pub use implicit::{ImplicitSolver, CG_TOLERANCE};
pub use list::DEFAULT_SKIN;
pub use oracle::{brute_force, OracleResult};
pub use params::{ContactParamError, ContactParams, Damping, Walls, LUBRICATION_SUBSTEPS_MAX};
pub use slots::{ContactLoad, ContactStats};
pub use subcycle::step_bodies;

/// Default number of contact sub-steps per fluid time step (module doc, "Stability analysis"):
/// every single saturated contact is monotone at `d = 12` (`c h/m_red ≤ 0.73`) and stable at
/// `d = 6` (`≤ 1.34 < 2`).
pub const DEFAULT_SUBSTEPS: usize = 8;

/// Contact sub-steps per fluid step recommended with [`Damping::Implicit`] (module doc,
/// "Implicit damping"): the spring's rate (≤ 3.4 per fluid step in the paper's dense beds at
/// s = 1/4) is resolved with `ω h ≤ 1.7`, stable for position Verlet (`ω h < 2`), and the
/// damping needs no resolution.
pub const IMPLICIT_SUBSTEPS: usize = 2;

/// Safety margin (lattice units) added to every pruning radius, far above round-off (≲ 1e-12
/// at coordinates of a few hundred) and far below any physical length: pruning (the broad
/// phase, module `broad`, and the narrow phase, module `list`) never drops a pair that the
/// exact criterion `|x_j − x_i| < reach` keeps.
const MARGIN: f64 = 1e-6;

/// The contact tests' shared scene.
#[cfg(test)]
pub(crate) mod fixture {
    use super::Walls;
    use crate::rigid::{Cylinder, Marker, Motion, Quat, RigidBody, Shape, Vec3, DEFAULT_MARKER_SPACING};
    use std::sync::Arc;

    /// Two free cylinders side by side, a third pinched between one of them and a moving
    /// prescribed one, all over the floor, every surface inside the lubrication range.
    pub(crate) fn scene() -> (Vec<RigidBody>, Vec<Vec<Marker>>, Walls) {
        let shape: Arc<dyn Shape> = Arc::new(Cylinder::new(6.0, 6.0));
        let m = shape.markers(DEFAULT_MARKER_SPACING);
        let tilt = |a: f64| Quat::from_axis_angle(&Vec3::y_axis(), a);
        let body = |x: f64, q: Quat, motion: Motion, v: Vec3, w: Vec3| {
            RigidBody::new(shape.clone(), 1.25, motion)
                .with_position(Vec3::new(x, 10.0, 3.4))
                .with_orientation(q)
                .with_velocities(v, w)
        };
        let bodies = vec![
            body(
                10.0,
                tilt(0.05),
                Motion::Free,
                Vec3::new(0.01, -0.004, -0.006),
                Vec3::new(0.001, 0.003, -0.002),
            ),
            body(
                16.3,
                tilt(-0.03),
                Motion::Free,
                Vec3::new(-0.02, 0.003, 0.001),
                Vec3::new(-0.002, 0.001, 0.004),
            ),
            body(
                3.75,
                tilt(0.02),
                Motion::constant(Vec3::new(0.015, 0.0, 0.0), Vec3::new(0.0, 0.0, 0.002)),
                Vec3::new(0.015, 0.0, 0.0),
                Vec3::new(0.0, 0.0, 0.002),
            ),
            body(22.6, tilt(0.01), Motion::Free, Vec3::new(-0.01, 0.0, 0.002), Vec3::new(0.0, -0.003, 0.001)),
        ];
        let markers = vec![m.clone(), m.clone(), m.clone(), m];
        (bodies, markers, Walls { planes: [[None, None], [None, None], [Some(0.0), None]] })
    }
}
