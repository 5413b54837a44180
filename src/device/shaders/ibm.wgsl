// The immersed-boundary markers on the device (src/device/markers.rs): marker kinematics, the
// stencils of src/ibm/stencil.rs, interpolation of the fluid velocity, direct forcing, spreading
// into the fluid's force field, and the bodies' loads. One thread per marker (or per chunk of a
// body's markers, or per body); thread index gid.x + gid.y * prm.row (a 2-D dispatch, since a
// dimension holds at most 65535 groups).
//
// Spreading is deterministic without floating-point atomics: every contribution w F (f32) is
// rounded once to a 64-bit fixed-point integer of scale 2^-40 and added with two 32-bit integer
// atomics (low word, then the high word with the carry the low addition produced). Integer
// addition is associative, so the sums, hence the force field, are the same bits whatever the
// order in which the threads arrive, the work-group size and the marker order. markers.rs says
// why the scale is enough.
//
// Storage of the fluid (common.wgsl): the shifted populations h_q in f<q>[n] on the padded grid,
// node (x, y, z) at (x+1) + px ((y+1) + py (z+1)); the force density in force_<a>[n] (f32 bits,
// declared here as atomic words: several threads store the same bits to a node).

struct IbmParams {
    nx: u32,
    ny: u32,
    nz: u32,
    px: u32,
    py: u32,
    n_markers: u32,
    n_bodies: u32,
    n_chunks: u32,
    // Threads of one row of the 2-D dispatch.
    row: u32,
    // Whether the fluid's time is odd (the AA layout of the populations).
    odd: u32,
    // Periodic axes (1) or walled (0).
    per_x: u32,
    per_y: u32,
    per_z: u32,
    // Rows of the interior sums, and which sums (0 before the forcing, 1 after the fluid step).
    n_rows: u32,
    slot: u32,
    pad2: u32,
    // The fluid's uniform body force.
    body_x: f32,
    body_y: f32,
    body_z: f32,
    pad3: f32,
}

@group(0) @binding(0) var<uniform> prm: IbmParams;
@group(0) @binding(1) var<storage, read> f0: array<f32>;
@group(0) @binding(2) var<storage, read> f1: array<f32>;
@group(0) @binding(3) var<storage, read> f2: array<f32>;
@group(0) @binding(4) var<storage, read> f3: array<f32>;
@group(0) @binding(5) var<storage, read> f4: array<f32>;
@group(0) @binding(6) var<storage, read> f5: array<f32>;
@group(0) @binding(7) var<storage, read> f6: array<f32>;
@group(0) @binding(8) var<storage, read> f7: array<f32>;
@group(0) @binding(9) var<storage, read> f8: array<f32>;
@group(0) @binding(10) var<storage, read> f9: array<f32>;
@group(0) @binding(11) var<storage, read> f10: array<f32>;
@group(0) @binding(12) var<storage, read> f11: array<f32>;
@group(0) @binding(13) var<storage, read> f12: array<f32>;
@group(0) @binding(14) var<storage, read> f13: array<f32>;
@group(0) @binding(15) var<storage, read> f14: array<f32>;
@group(0) @binding(16) var<storage, read> f15: array<f32>;
@group(0) @binding(17) var<storage, read> f16: array<f32>;
@group(0) @binding(18) var<storage, read> f17: array<f32>;
@group(0) @binding(19) var<storage, read> f18: array<f32>;
// The fluid's force density field, f32 bits per padded node.
@group(0) @binding(20) var<storage, read_write> force_x: array<atomic<u32>>;
@group(0) @binding(21) var<storage, read_write> force_y: array<atomic<u32>>;
@group(0) @binding(22) var<storage, read_write> force_z: array<atomic<u32>>;
// Fixed-point sums of the step's spreading, per padded node: low word at 2n, high at 2n + 1.
@group(0) @binding(23) var<storage, read_write> acc_x: array<atomic<u32>>;
@group(0) @binding(24) var<storage, read_write> acc_y: array<atomic<u32>>;
@group(0) @binding(25) var<storage, read_write> acc_z: array<atomic<u32>>;
// Per marker: body-frame position (xyz) and area weight (w), uploaded once.
@group(0) @binding(26) var<storage, read> marker_body: array<vec4<f32>>;
// Per marker: its body.
@group(0) @binding(27) var<storage, read> owner: array<u32>;
// Per body, 7 words-quads (the step's upload): origin (i32 xyz), the centre's offset from it
// (f32 xyz), the rotation matrix's rows (f32), velocity (f32), angular velocity (f32).
@group(0) @binding(28) var<storage, read> bodies: array<vec4<u32>>;
// Per marker: first node per axis and the three lengths (bits 0-7 x, 8-15 y, 16-23 z).
@group(0) @binding(29) var<storage, read_write> stencil_n: array<vec4<u32>>;
// Per marker, three entries (axis x, y, z): the kept points' 1-D weights.
@group(0) @binding(30) var<storage, read_write> stencil_w: array<vec4<f32>>;
// Per marker: the arm R r from the body's centre (world frame).
@group(0) @binding(31) var<storage, read_write> arm: array<vec4<f32>>;
// Per marker: the solid velocity U = v + w x (R r).
@group(0) @binding(32) var<storage, read_write> solid_u: array<vec4<f32>>;
// Per marker: the interpolated fluid velocity u_m.
@group(0) @binding(33) var<storage, read_write> marker_u: array<vec4<f32>>;
// Per marker: this iteration's force increment 2 (U - u) A, and the step's total.
@group(0) @binding(34) var<storage, read_write> increment: array<vec4<f32>>;
@group(0) @binding(35) var<storage, read_write> total: array<vec4<f32>>;
// Chunks of a body's markers: (first marker, end, -, -); per body (first chunk, end, -, -).
@group(0) @binding(36) var<storage, read> chunks: array<vec4<u32>>;
@group(0) @binding(37) var<storage, read> body_chunks: array<vec4<u32>>;
// Per chunk (2 entries) and per body (2 entries): -sum F and -sum r x F.
@group(0) @binding(38) var<storage, read_write> partial: array<vec4<f32>>;
@group(0) @binding(39) var<storage, read_write> loads: array<vec4<f32>>;
// The lowest marker that could not be given a stencil (0xffffffff: none).
@group(0) @binding(40) var<storage, read_write> status: array<atomic<u32>>;
// Interior sums. Per body two entries: (kind: 0 none, 1 sphere, 2 cylinder, 3 cuboid; nodes per
// axis of its box; first row; -), then f32 bits of (radius or half extents; half-length; -;
// the box's reach from the centre).
@group(0) @binding(41) var<storage, read> shapes: array<vec4<u32>>;
// Per row of a body's box: (body, y index, z index, -).
@group(0) @binding(42) var<storage, read> rows: array<vec4<u32>>;
// Per row, four entries: the sums (P, L, V) and their compensations, see `interior_rows`.
@group(0) @binding(43) var<storage, read_write> row_sums: array<vec4<f32>>;
// Per body and slot (before, after), four entries as `row_sums`.
@group(0) @binding(44) var<storage, read_write> interior: array<vec4<f32>>;

// Work-group size, the kernel (0 linear, 1 Roma 3-point, 2 Peskin 4-point) and its width.
override WG: u32 = 64u;
override KERNEL: u32 = 1u;
override WIDTH: u32 = 3u;

fn thread(gid: vec3<u32>) -> u32 {
    return gid.x + gid.y * prm.row;
}

// The 1-D kernel phi(r), as src/ibm/kernel.rs writes it (same operations, in f32).
fn phi(r: f32) -> f32 {
    let a = abs(r);
    if KERNEL == 0u {
        if a < 1.0 {
            return 1.0 - a;
        }
        return 0.0;
    }
    if KERNEL == 1u {
        if a <= 0.5 {
            return (1.0 + sqrt(1.0 - 3.0 * a * a)) / 3.0;
        } else if a < 1.5 {
            let b = 1.0 - a;
            return (5.0 - 3.0 * a - sqrt(1.0 - 3.0 * b * b)) / 6.0;
        }
        return 0.0;
    }
    if a <= 1.0 {
        return (3.0 - 2.0 * a + sqrt(1.0 + 4.0 * a - 4.0 * a * a)) / 8.0;
    } else if a < 2.0 {
        return (5.0 - 2.0 * a - sqrt(-7.0 + 12.0 * a - 4.0 * a * a)) / 8.0;
    }
    return 0.0;
}

fn support() -> f32 {
    return f32(WIDTH) * 0.5;
}

fn axis_n(a: u32) -> u32 {
    if a == 0u {
        return prm.nx;
    }
    if a == 1u {
        return prm.ny;
    }
    return prm.nz;
}

fn axis_periodic(a: u32) -> bool {
    if a == 0u {
        return prm.per_x != 0u;
    }
    if a == 1u {
        return prm.per_y != 0u;
    }
    return prm.per_z != 0u;
}

fn body_f32(b: u32, k: u32) -> vec3<f32> {
    return bitcast<vec3<f32>>(bodies[7u * b + k].xyz);
}

// The world-frame arm R r of marker m.
fn marker_arm(m: u32) -> vec3<f32> {
    let b = owner[m];
    let r = marker_body[m].xyz;
    let r0 = body_f32(b, 2u);
    let r1 = body_f32(b, 3u);
    let r2 = body_f32(b, 4u);
    return vec3<f32>(
        r0.x * r.x + r0.y * r.y + r0.z * r.z,
        r1.x * r.x + r1.y * r.y + r1.z * r.z,
        r2.x * r.x + r2.y * r.y + r2.z * r.z,
    );
}

// Marker kinematics and the stencil (src/ibm/stencil.rs): positions are taken relative to the
// body's integer origin, so the offsets x - j that the weights need keep the precision of the
// arm, not of the box's size. Per axis the W points j = floor(x - h) + 1 + k; on a periodic
// axis wrapped into [0, n); on a walled axis the points outside [0, n) dropped and the kept
// weights divided by their sum when a dropped weight was non-zero. A marker outside the box on
// a walled axis, or not finite, gets no stencil and is reported in `status`.
@compute @workgroup_size(WG)
fn place(@builtin(global_invocation_id) gid: vec3<u32>) {
    let m = thread(gid);
    if m >= prm.n_markers {
        return;
    }
    let b = owner[m];
    let d = marker_arm(m);
    let origin = bitcast<vec3<i32>>(bodies[7u * b].xyz);
    let frac = body_f32(b, 1u);
    let v = body_f32(b, 5u);
    let w = body_f32(b, 6u);
    arm[m] = vec4<f32>(d, 0.0);
    solid_u[m] = vec4<f32>(v + cross(w, d), 0.0);
    total[m] = vec4<f32>(0.0);
    let x = frac + d;
    var first = vec3<u32>(0u);
    var lens = 0u;
    var ok = true;
    for (var a = 0u; a < 3u; a++) {
        let n = axis_n(a);
        let o = origin[a];
        let xr = x[a];
        if !(abs(xr) <= 3.0e38) {
            ok = false;
        }
        let periodic = axis_periodic(a);
        if !periodic && !(xr >= -0.5 - f32(o) && xr <= f32(n) - 0.5 - f32(o)) {
            ok = false;
        }
        if !ok {
            break;
        }
        let lo_rel = i32(floor(xr - support())) + 1;
        let lo = o + lo_rel;
        var wts = vec4<f32>(0.0);
        var kept = 0u;
        if periodic {
            let ni = i32(n);
            first[a] = u32(((lo % ni) + ni) % ni);
            for (var k = 0u; k < WIDTH; k++) {
                wts[k] = phi(xr - f32(lo_rel + i32(k)));
            }
            kept = WIDTH;
        } else {
            var sum = 0.0;
            var dropped = 0.0;
            for (var k = 0u; k < WIDTH; k++) {
                let j = lo + i32(k);
                let p = phi(xr - f32(lo_rel + i32(k)));
                if j >= 0 && j < i32(n) {
                    if kept == 0u {
                        first[a] = u32(j);
                    }
                    wts[kept] = p;
                    sum = sum + p;
                    kept += 1u;
                } else {
                    dropped = dropped + p;
                }
            }
            if dropped > 0.0 {
                for (var k = 0u; k < kept; k++) {
                    wts[k] = wts[k] / sum;
                }
            }
        }
        stencil_w[3u * m + a] = wts;
        lens = lens | (kept << (8u * a));
    }
    if !ok {
        lens = 0u;
        atomicMin(&status[0], m);
    }
    stencil_n[m] = vec4<u32>(first, lens);
}

// The k-th node of a stencil on axis a from its first node (periodic: wrapped; walled: the kept
// nodes are consecutive).
fn node(a: u32, first: u32, k: u32) -> u32 {
    let n = axis_n(a);
    if axis_periodic(a) {
        return (first + k) % n;
    }
    return first + k;
}

fn padded(x: u32, y: u32, z: u32) -> u32 {
    return (x + 1u) + prm.px * ((y + 1u) + prm.py * (z + 1u));
}

fn load_force(p: u32) -> vec3<f32> {
    return vec3<f32>(
        bitcast<f32>(atomicLoad(&force_x[p])),
        bitcast<f32>(atomicLoad(&force_y[p])),
        bitcast<f32>(atomicLoad(&force_z[p])),
    );
}

// The momentum j and the density deviation (w) at padded node p, from the pre-collision
// populations whatever the AA parity (Fluid::shifted_populations), with the CPU's sums in its
// order (lbm::collision::moments).
fn moments(p: u32) -> vec4<f32> {
    let px = prm.px;
    let pxy = px * prm.py;
    var h: array<f32, 19>;
    h[0] = f0[p];
    if prm.odd != 0u {
        h[1] = f2[p - 1u];
        h[2] = f1[p + 1u];
        h[3] = f4[p - px];
        h[4] = f3[p + px];
        h[5] = f6[p - pxy];
        h[6] = f5[p + pxy];
        h[7] = f8[p - 1u - px];
        h[8] = f7[p + 1u + px];
        h[9] = f10[p - 1u + px];
        h[10] = f9[p + 1u - px];
        h[11] = f12[p - 1u - pxy];
        h[12] = f11[p + 1u + pxy];
        h[13] = f14[p - 1u + pxy];
        h[14] = f13[p + 1u - pxy];
        h[15] = f16[p - px - pxy];
        h[16] = f15[p + px + pxy];
        h[17] = f18[p - px + pxy];
        h[18] = f17[p + px - pxy];
    } else {
        h[1] = f1[p];
        h[2] = f2[p];
        h[3] = f3[p];
        h[4] = f4[p];
        h[5] = f5[p];
        h[6] = f6[p];
        h[7] = f7[p];
        h[8] = f8[p];
        h[9] = f9[p];
        h[10] = f10[p];
        h[11] = f11[p];
        h[12] = f12[p];
        h[13] = f13[p];
        h[14] = f14[p];
        h[15] = f15[p];
        h[16] = f16[p];
        h[17] = f17[p];
        h[18] = f18[p];
    }
    var drho = h[0];
    for (var i = 1u; i < 19u; i++) {
        drho = drho + h[i];
    }
    let jx = (h[1] - h[2]) + (h[7] - h[8]) + (h[9] - h[10]) + (h[11] - h[12]) + (h[13] - h[14]);
    let jy = (h[3] - h[4]) + (h[7] - h[8]) + (h[10] - h[9]) + (h[15] - h[16]) + (h[17] - h[18]);
    let jz = (h[5] - h[6]) + (h[11] - h[12]) + (h[14] - h[13]) + (h[15] - h[16]) + (h[18] - h[17]);
    return vec4<f32>(jx, jy, jz, drho);
}

// The fluid velocity u = (j + F/2)/rho at padded node p, F the field plus the body force (added
// in f32, as the CPU).
fn velocity(p: u32) -> vec3<f32> {
    let m = moments(p);
    let rho = 1.0 + m.w;
    let f = load_force(p) + vec3<f32>(prm.body_x, prm.body_y, prm.body_z);
    return vec3<f32>((m.x + 0.5 * f.x) / rho, (m.y + 0.5 * f.y) / rho, (m.z + 0.5 * f.z) / rho);
}

// u_m = sum_n delta_mn u_n over the stencil in the CPU's order (z, then y, then x), with the
// 3-D weight (phi_z phi_y) phi_x (Stencils::for_each_node).
@compute @workgroup_size(WG)
fn interpolate(@builtin(global_invocation_id) gid: vec3<u32>) {
    let m = thread(gid);
    if m >= prm.n_markers {
        return;
    }
    let st = stencil_n[m];
    let wx = stencil_w[3u * m];
    let wy = stencil_w[3u * m + 1u];
    let wz = stencil_w[3u * m + 2u];
    let lx = st.w & 255u;
    let ly = (st.w >> 8u) & 255u;
    let lz = (st.w >> 16u) & 255u;
    var acc = vec3<f32>(0.0);
    for (var c = 0u; c < lz; c++) {
        let z = node(2u, st.z, c);
        for (var b = 0u; b < ly; b++) {
            let y = node(1u, st.y, b);
            let wzy = wz[c] * wy[b];
            for (var a = 0u; a < lx; a++) {
                let x = node(0u, st.x, a);
                let w = wzy * wx[a];
                let u = velocity(padded(x, y, z));
                acc = vec3<f32>(acc.x + w * u.x, acc.y + w * u.y, acc.z + w * u.z);
            }
        }
    }
    marker_u[m] = vec4<f32>(acc, 0.0);
}

// Direct forcing (coupling::forcing): the increment 2 (U - u) A (rho_m = 1), added to the
// marker's total of the step.
@compute @workgroup_size(WG)
fn direct_forcing(@builtin(global_invocation_id) gid: vec3<u32>) {
    let m = thread(gid);
    if m >= prm.n_markers {
        return;
    }
    let area = marker_body[m].w;
    let inc = 2.0 * (solid_u[m].xyz - marker_u[m].xyz) * area;
    increment[m] = vec4<f32>(inc, 0.0);
    total[m] = vec4<f32>(total[m].xyz + inc, 0.0);
}

// Adds v to the 64-bit fixed-point sum (scale 2^-40) of component c at padded node p: v 2^40
// rounded to an integer s (exact for |v| >= 2^-17), split exactly into s = hi 2^32 + lo with
// lo in [0, 2^32); the low word's addition returns the old word, from which the carry into the
// high word follows. The sums are exact modulo 2^64, so in any order the same.
fn add_fixed(c: u32, p: u32, v: f32) {
    let s = round(v * 1099511627776.0);
    let hi_f = floor(s * (1.0 / 4294967296.0));
    let lo = u32(s - hi_f * 4294967296.0);
    let hi = bitcast<u32>(i32(hi_f));
    var old: u32;
    if c == 0u {
        old = atomicAdd(&acc_x[2u * p], lo);
    } else if c == 1u {
        old = atomicAdd(&acc_y[2u * p], lo);
    } else {
        old = atomicAdd(&acc_z[2u * p], lo);
    }
    let carry = select(0u, 1u, old + lo < old);
    if c == 0u {
        atomicAdd(&acc_x[2u * p + 1u], hi + carry);
    } else if c == 1u {
        atomicAdd(&acc_y[2u * p + 1u], hi + carry);
    } else {
        atomicAdd(&acc_z[2u * p + 1u], hi + carry);
    }
}

// The f32 nearest (within an ulp) to the fixed-point value (lo, hi): the magnitude's two words
// converted and added, the sign applied after.
fn fixed_to_f32(lo: u32, hi: u32) -> f32 {
    var l = lo;
    var h = hi;
    var sign = 1.0;
    if (hi >> 31u) != 0u {
        l = ~lo + 1u;
        h = ~hi + select(0u, 1u, l == 0u);
        sign = -1.0;
    }
    return sign * ((f32(h) * 4294967296.0 + f32(l)) * (1.0 / 1099511627776.0));
}

// Spreading (ibm::transfer::spread): each stencil node's sums get w F of the marker's increment.
@compute @workgroup_size(WG)
fn spread(@builtin(global_invocation_id) gid: vec3<u32>) {
    let m = thread(gid);
    if m >= prm.n_markers {
        return;
    }
    let st = stencil_n[m];
    let wx = stencil_w[3u * m];
    let wy = stencil_w[3u * m + 1u];
    let wz = stencil_w[3u * m + 2u];
    let lx = st.w & 255u;
    let ly = (st.w >> 8u) & 255u;
    let lz = (st.w >> 16u) & 255u;
    let f = increment[m].xyz;
    for (var c = 0u; c < lz; c++) {
        let z = node(2u, st.z, c);
        for (var b = 0u; b < ly; b++) {
            let y = node(1u, st.y, b);
            let wzy = wz[c] * wy[b];
            for (var a = 0u; a < lx; a++) {
                let x = node(0u, st.x, a);
                let w = wzy * wx[a];
                let p = padded(x, y, z);
                add_fixed(0u, p, w * f.x);
                add_fixed(1u, p, w * f.y);
                add_fixed(2u, p, w * f.z);
            }
        }
    }
}

// The force field at every stencil node := its fixed-point sums as f32. Every marker whose
// stencil holds a node stores the same bits there (the sums are complete: a separate dispatch).
// With `clear`, the sums and the field are zeroed there instead (the previous step's stencils,
// before the new ones are placed).
override CLEAR: bool = false;

@compute @workgroup_size(WG)
fn settle(@builtin(global_invocation_id) gid: vec3<u32>) {
    let m = thread(gid);
    if m >= prm.n_markers {
        return;
    }
    let st = stencil_n[m];
    let lx = st.w & 255u;
    let ly = (st.w >> 8u) & 255u;
    let lz = (st.w >> 16u) & 255u;
    for (var c = 0u; c < lz; c++) {
        let z = node(2u, st.z, c);
        for (var b = 0u; b < ly; b++) {
            let y = node(1u, st.y, b);
            for (var a = 0u; a < lx; a++) {
                let x = node(0u, st.x, a);
                let p = padded(x, y, z);
                if CLEAR {
                    atomicStore(&acc_x[2u * p], 0u);
                    atomicStore(&acc_x[2u * p + 1u], 0u);
                    atomicStore(&acc_y[2u * p], 0u);
                    atomicStore(&acc_y[2u * p + 1u], 0u);
                    atomicStore(&acc_z[2u * p], 0u);
                    atomicStore(&acc_z[2u * p + 1u], 0u);
                    atomicStore(&force_x[p], 0u);
                    atomicStore(&force_y[p], 0u);
                    atomicStore(&force_z[p], 0u);
                } else {
                    let fx = fixed_to_f32(atomicLoad(&acc_x[2u * p]), atomicLoad(&acc_x[2u * p + 1u]));
                    let fy = fixed_to_f32(atomicLoad(&acc_y[2u * p]), atomicLoad(&acc_y[2u * p + 1u]));
                    let fz = fixed_to_f32(atomicLoad(&acc_z[2u * p]), atomicLoad(&acc_z[2u * p + 1u]));
                    atomicStore(&force_x[p], bitcast<u32>(fx));
                    atomicStore(&force_y[p], bitcast<u32>(fy));
                    atomicStore(&force_z[p], bitcast<u32>(fz));
                }
            }
        }
    }
}

// Loads, first stage: per chunk of a body's markers (a fixed number, whatever the work-group
// size), -sum F_m and -sum r_m x F_m over the step's totals, serially in marker order.
@compute @workgroup_size(WG)
fn chunk_loads(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = thread(gid);
    if k >= prm.n_chunks {
        return;
    }
    let range = chunks[k];
    var f = vec3<f32>(0.0);
    var t = vec3<f32>(0.0);
    for (var m = range.x; m < range.y; m++) {
        let fm = total[m].xyz;
        f = f - fm;
        t = t - cross(arm[m].xyz, fm);
    }
    partial[2u * k] = vec4<f32>(f, 0.0);
    partial[2u * k + 1u] = vec4<f32>(t, 0.0);
}

// Loads, second stage: per body, its chunks' sums in chunk order.
@compute @workgroup_size(WG)
fn body_loads(@builtin(global_invocation_id) gid: vec3<u32>) {
    let b = thread(gid);
    if b >= prm.n_bodies {
        return;
    }
    let range = body_chunks[b];
    var f = vec3<f32>(0.0);
    var t = vec3<f32>(0.0);
    for (var k = range.x; k < range.y; k++) {
        f = f + partial[2u * k].xyz;
        t = t + partial[2u * k + 1u].xyz;
    }
    loads[2u * b] = vec4<f32>(f, 0.0);
    loads[2u * b + 1u] = vec4<f32>(t, 0.0);
}

// ---- Interior sums (coupling::interior): P = sum a j, L = sum a r x j, V = sum a over the
// nodes of a body's box, a = clamp(1/2 - sd, 0, 1), sd the shape's signed distance at the node
// (body frame), r the node's unwrapped offset from the centre. Each sum is kept with a running
// compensation (Neumaier's variant of Kahan's summation), so that the difference of the sums
// before and after a step keeps the accuracy of the momenta rather than of the sums' size.

// The shape's signed distance at body-frame point q (src/rigid: sphere, cylinder about body z,
// cuboid), in the CPU's operations.
fn signed_distance(kind: u32, d: vec4<f32>, q: vec3<f32>) -> f32 {
    if kind == 1u {
        return length(q) - d.x;
    }
    if kind == 2u {
        let qr = sqrt(q.x * q.x + q.y * q.y) - d.x;
        let qz = abs(q.z) - d.y;
        let a = max(qr, 0.0);
        let b = max(qz, 0.0);
        return min(max(qr, qz), 0.0) + sqrt(a * a + b * b);
    }
    let e = abs(q) - d.xyz;
    return length(max(e, vec3<f32>(0.0))) + min(max(max(e.x, e.y), e.z), 0.0);
}

// s[i] + x with the rounding error kept in c[i].
fn neumaier(s: ptr<function, array<f32, 7>>, c: ptr<function, array<f32, 7>>, i: u32, x: f32) {
    let a = (*s)[i];
    let t = a + x;
    if abs(a) >= abs(x) {
        (*c)[i] = (*c)[i] + ((a - t) + x);
    } else {
        (*c)[i] = (*c)[i] + ((x - t) + a);
    }
    (*s)[i] = t;
}

// The node index of unwrapped coordinate j on axis a, or 0xffffffff outside a walled axis.
fn wrap(a: u32, j: i32) -> u32 {
    let n = i32(axis_n(a));
    if axis_periodic(a) {
        return u32(((j % n) + n) % n);
    }
    if j < 0 || j >= n {
        return 0xffffffffu;
    }
    return u32(j);
}

fn store_sums(out: u32, s: array<f32, 7>, c: array<f32, 7>, dst: u32) {
    if dst == 0u {
        row_sums[out] = vec4<f32>(s[0], s[1], s[2], s[3]);
        row_sums[out + 1u] = vec4<f32>(s[4], s[5], s[6], 0.0);
        row_sums[out + 2u] = vec4<f32>(c[0], c[1], c[2], c[3]);
        row_sums[out + 3u] = vec4<f32>(c[4], c[5], c[6], 0.0);
    } else {
        interior[out] = vec4<f32>(s[0], s[1], s[2], s[3]);
        interior[out + 1u] = vec4<f32>(s[4], s[5], s[6], 0.0);
        interior[out + 2u] = vec4<f32>(c[0], c[1], c[2], c[3]);
        interior[out + 3u] = vec4<f32>(c[4], c[5], c[6], 0.0);
    }
}

// The interval of t over which p + t v stays within h of the origin (|p + t v| < h), or an
// empty one (first > second).
fn slab(p: f32, v: f32, h: f32) -> vec2<f32> {
    if abs(v) < 1e-12 {
        if abs(p) < h {
            return vec2<f32>(-3.0e38, 3.0e38);
        }
        return vec2<f32>(1.0, -1.0);
    }
    let ta = (-h - p) / v;
    let tb = (h - p) / v;
    return vec2<f32>(min(ta, tb), max(ta, tb));
}

// The interval of t over which p + t v lies in the disk |q_xy| < r (of the first `n` axes of
// a sphere, n = 3, or a cylinder's cross-section, n = 2), or an empty one.
fn disk(p: vec3<f32>, v: vec3<f32>, r: f32, n: u32) -> vec2<f32> {
    var pp = p;
    var vv = v;
    if n == 2u {
        pp.z = 0.0;
        vv.z = 0.0;
    }
    let a = dot(vv, vv);
    let c = dot(pp, pp) - r * r;
    if a < 1e-12 {
        if c < 0.0 {
            return vec2<f32>(-3.0e38, 3.0e38);
        }
        return vec2<f32>(1.0, -1.0);
    }
    let b = dot(pp, vv);
    let disc = b * b - a * c;
    if disc < 0.0 {
        return vec2<f32>(1.0, -1.0);
    }
    let sq = sqrt(disc);
    return vec2<f32>((-b - sq) / a, (-b + sq) / a);
}

fn meet(a: vec2<f32>, b: vec2<f32>) -> vec2<f32> {
    return vec2<f32>(max(a.x, b.x), min(a.y, b.y));
}

// The chord of the body-frame line p + t v through the shape grown by g (the sphere of radius
// r + g, the flat-capped cylinder of radius r + g and half-length h + g, the box of half
// extents + g): for g > 1/2 a superset, with a margin, of the nodes with sd < 1/2.
fn chord(kind: u32, d: vec4<f32>, p: vec3<f32>, v: vec3<f32>, g: f32) -> vec2<f32> {
    if kind == 1u {
        return disk(p, v, d.x + g, 3u);
    }
    if kind == 2u {
        return meet(disk(p, v, d.x + g, 2u), slab(p.z, v.z, d.y + g));
    }
    return meet(meet(slab(p.x, v.x, d.x + g), slab(p.y, v.y, d.y + g)), slab(p.z, v.z, d.z + g));
}

// First stage: one row of a body's box (its nodes in x order), the box being the W^3 nodes
// from floor(centre - reach) on, reach the bounding radius plus 1/2 (every node with
// sd < 1/2 lies in it). Only the row's nodes within the chord of the shape grown by 0.51 (and
// one node beyond each end, for the chord's rounding) are visited: the others have a = 0 and
// add nothing, so the sums are those of the whole row, in the same order.
@compute @workgroup_size(WG)
fn interior_rows(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = thread(gid);
    if k >= prm.n_rows {
        return;
    }
    let row = rows[k];
    let b = row.x;
    let kind = shapes[2u * b].x;
    let w = shapes[2u * b].y;
    let d = bitcast<vec4<f32>>(shapes[2u * b + 1u]);
    let origin = bitcast<vec3<i32>>(bodies[7u * b].xyz);
    let frac = body_f32(b, 1u);
    let r0 = body_f32(b, 2u);
    let r1 = body_f32(b, 3u);
    let r2 = body_f32(b, 4u);
    let lo = vec3<i32>(floor(frac - vec3<f32>(d.w)));
    let yr = lo.y + i32(row.y);
    let zr = lo.z + i32(row.z);
    let y = wrap(1u, origin.y + yr);
    let z = wrap(2u, origin.z + zr);
    var s: array<f32, 7>;
    var c: array<f32, 7>;
    for (var i = 0u; i < 7u; i++) {
        s[i] = 0.0;
        c[i] = 0.0;
    }
    // Body frame along the row: q = R^T r = qa + t r0 with t = r.x.
    let qa = r1 * (f32(yr) - frac.y) + r2 * (f32(zr) - frac.z);
    let span = chord(kind, d, qa, r0, 0.51);
    var first = 0u;
    var end = 0u;
    if span.x <= span.y {
        // Nodes xr with xr - frac.x in the chord, one more each side, within the box.
        let a = clamp(ceil(span.x + frac.x) - f32(lo.x) - 1.0, 0.0, f32(w));
        let e = clamp(floor(span.y + frac.x) - f32(lo.x) + 2.0, 0.0, f32(w));
        first = u32(a);
        end = u32(e);
    }
    if y != 0xffffffffu && z != 0xffffffffu {
        for (var ix = first; ix < end; ix++) {
            let xr = lo.x + i32(ix);
            let x = wrap(0u, origin.x + xr);
            if x == 0xffffffffu {
                continue;
            }
            let r = vec3<f32>(f32(xr) - frac.x, f32(yr) - frac.y, f32(zr) - frac.z);
            // Body frame: R^T r.
            let q = r0 * r.x + r1 * r.y + r2 * r.z;
            let alpha = clamp(0.5 - signed_distance(kind, d, q), 0.0, 1.0);
            if alpha > 0.0 {
                let m = moments(padded(x, y, z)).xyz * alpha;
                let l = cross(r, m);
                neumaier(&s, &c, 0u, m.x);
                neumaier(&s, &c, 1u, m.y);
                neumaier(&s, &c, 2u, m.z);
                neumaier(&s, &c, 3u, l.x);
                neumaier(&s, &c, 4u, l.y);
                neumaier(&s, &c, 5u, l.z);
                neumaier(&s, &c, 6u, alpha);
            }
        }
    }
    store_sums(4u * k, s, c, 0u);
}

// Second stage: per body, its rows in order (sums added with compensation, compensations
// added), into slot prm.slot.
@compute @workgroup_size(WG)
fn interior_bodies(@builtin(global_invocation_id) gid: vec3<u32>) {
    let b = thread(gid);
    if b >= prm.n_bodies {
        return;
    }
    let w = shapes[2u * b].y;
    let first = shapes[2u * b].z;
    var s: array<f32, 7>;
    var c: array<f32, 7>;
    for (var i = 0u; i < 7u; i++) {
        s[i] = 0.0;
        c[i] = 0.0;
    }
    for (var k = first; k < first + w * w; k++) {
        let a0 = row_sums[4u * k];
        let a1 = row_sums[4u * k + 1u];
        let e0 = row_sums[4u * k + 2u];
        let e1 = row_sums[4u * k + 3u];
        var rs = array<f32, 7>(a0.x, a0.y, a0.z, a0.w, a1.x, a1.y, a1.z);
        var rc = array<f32, 7>(e0.x, e0.y, e0.z, e0.w, e1.x, e1.y, e1.z);
        for (var i = 0u; i < 7u; i++) {
            neumaier(&s, &c, i, rs[i]);
            c[i] = c[i] + rc[i];
        }
    }
    store_sums(8u * b + 4u * prm.slot, s, c, 1u);
}
