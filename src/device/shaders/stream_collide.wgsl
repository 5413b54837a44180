// The fused AA-pattern stream-collide sweep of the D3Q19 fluid, one thread per interior node:
// the device's copy of src/lbm/kernel.rs with the collision of src/lbm/collision.rs, the same
// operations in the same order (sums, fused multiply-adds, one division).
//
// Even sweep: node x reads h_i from its own slot (x, i) and writes h_i* to (x, opp(i)).
// Odd sweep: node x reads h_i from (x - c_i, opp(i)) and writes h_i* to (x + c_i, i).
// The slots a node writes are the slots it read, and no two nodes share one, so the update is
// in place and race-free for any work-group size.
//
// Preceded by common.wgsl (bindings, Params, WG).

// Odd or even sweep, TRT or BGK, force field on or off: fixed when the pipeline is made.
override ODD: bool = false;
override TRT: bool = false;
override FF: bool = false;

// The post-collision pair (h_i*, h_opp(i)*) from (a, b) = (h_i, h_opp(i)), with cu = c_i . u,
// cf = c_i . F and the pair's coefficients (collision.rs, `collide`, pass 2).
fn pair(a: real, b: real, cu: real, cf: real, p: real, r: real, q: real, n: real, m: real) -> vec2<real> {
    let e = fma(r, cu * cu, fma(n, cu * cf, p));
    let o = fma(q, cu, m * cf);
    if TRT {
        let md = prm.hm * (a - b);
        let sum = a + b;
        return vec2<real>((a - fma(prm.hp, sum, md)) + (e + o), (b - fma(prm.hp, sum, -md)) + (e - o));
    }
    return vec2<real>(fma(prm.keep, a, e + o), fma(prm.keep, b, e - o));
}

@compute @workgroup_size(WG)
fn stream_collide(@builtin(global_invocation_id) gid: vec3<u32>) {
    let x = gid.x;
    if x >= prm.nx {
        return;
    }
    let px = prm.px;
    let pxy = px * prm.py;
    // Interior node (x, y, z) of the padded grid; y < ny and z < nz by the dispatch's size.
    let p = (x + 1u) + px * ((gid.y + 1u) + prm.py * (gid.z + 1u));
    if ((solid[p >> 5u] >> (p & 31u)) & 1u) != 0u {
        return;
    }
    let o1 = 1u;
    let o3 = px;
    let o5 = pxy;
    let o7 = 1u + px;
    let o9 = 1u - px;
    let o11 = 1u + pxy;
    let o13 = 1u - pxy;
    let o15 = px + pxy;
    let o17 = px - pxy;

    // Reads. Pair (i, j = opp(i)): even a = f_i[p], b = f_j[p]; odd a = f_j[p - o_i],
    // b = f_i[p + o_i] (o_i the padded offset of c_i; u32 arithmetic wraps, and the result is a
    // neighbour of an interior node, so in the padded grid).
    let h0 = f0[p];
    var a1: real;
    var b1: real;
    var a3: real;
    var b3: real;
    var a5: real;
    var b5: real;
    var a7: real;
    var b7: real;
    var a9: real;
    var b9: real;
    var a11: real;
    var b11: real;
    var a13: real;
    var b13: real;
    var a15: real;
    var b15: real;
    var a17: real;
    var b17: real;
    if ODD {
        a1 = f2[p - o1];
        b1 = f1[p + o1];
        a3 = f4[p - o3];
        b3 = f3[p + o3];
        a5 = f6[p - o5];
        b5 = f5[p + o5];
        a7 = f8[p - o7];
        b7 = f7[p + o7];
        a9 = f10[p - o9];
        b9 = f9[p + o9];
        a11 = f12[p - o11];
        b11 = f11[p + o11];
        a13 = f14[p - o13];
        b13 = f13[p + o13];
        a15 = f16[p - o15];
        b15 = f15[p + o15];
        a17 = f18[p - o17];
        b17 = f17[p + o17];
    } else {
        a1 = f1[p];
        b1 = f2[p];
        a3 = f3[p];
        b3 = f4[p];
        a5 = f5[p];
        b5 = f6[p];
        a7 = f7[p];
        b7 = f8[p];
        a9 = f9[p];
        b9 = f10[p];
        a11 = f11[p];
        b11 = f12[p];
        a13 = f13[p];
        b13 = f14[p];
        a15 = f15[p];
        b15 = f16[p];
        a17 = f17[p];
        b17 = f18[p];
    }

    // Force: the body force, plus the node's force density when the field is on.
    var fx = prm.body_x;
    var fy = prm.body_y;
    var fz = prm.body_z;
    if FF {
        fx = force_x[p] + prm.body_x;
        fy = force_y[p] + prm.body_y;
        fz = force_z[p] + prm.body_z;
    }

    // Moments from pair sums and differences, in the CPU's order.
    let s0 = a1 + b1;
    let d0 = a1 - b1;
    let s1 = a3 + b3;
    let d1 = a3 - b3;
    let s2 = a5 + b5;
    let d2 = a5 - b5;
    let s3 = a7 + b7;
    let d3 = a7 - b7;
    let s4 = a9 + b9;
    let d4 = a9 - b9;
    let s5 = a11 + b11;
    let d5 = a11 - b11;
    let s6 = a13 + b13;
    let d6 = a13 - b13;
    let s7 = a15 + b15;
    let d7 = a15 - b15;
    let s8 = a17 + b17;
    let d8 = a17 - b17;
    let drho = h0 + ((((s0 + s1) + s2) + (s3 + s4)) + (s5 + s6) + (s7 + s8));
    let jx = ((d0 + (d3 + d4)) + (d5 + d6));
    let jy = ((d1 + (d3 - d4)) + (d7 + d8));
    let jz = ((d2 + (d5 - d6)) + (d7 - d8));
    let rho = 1.0 + drho;
    let inv_rho = 1.0 / rho;
    let ux = fma(0.5, fx, jx) * inv_rho;
    let uy = fma(0.5, fy, jy) * inv_rho;
    let uz = fma(0.5, fz, jz) * inv_rho;
    let usq = fma(ux, ux, fma(uy, uy, uz * uz));
    let uf = fma(ux, fx, fma(uy, fy, uz * fz));
    let g = fma(prm.omega, fma(-1.5, rho * usq, drho), -(prm.sp3 * uf));
    let p1 = prm.w1 * g;
    let p2 = prm.w2 * g;
    let r1 = prm.r1 * rho;
    let r2 = prm.r2 * rho;
    let q1 = prm.q1 * rho;
    let q2 = prm.q2 * rho;

    // Writes: h_i* to b's slot, h_opp(i)* to a's slot.
    f0[p] = fma(prm.keep, h0, prm.w0 * g);
    let v1 = pair(a1, b1, ux, fx, p1, r1, q1, prm.n1, prm.m1);
    let v3 = pair(a3, b3, uy, fy, p1, r1, q1, prm.n1, prm.m1);
    let v5 = pair(a5, b5, uz, fz, p1, r1, q1, prm.n1, prm.m1);
    let v7 = pair(a7, b7, ux + uy, fx + fy, p2, r2, q2, prm.n2, prm.m2);
    let v9 = pair(a9, b9, ux - uy, fx - fy, p2, r2, q2, prm.n2, prm.m2);
    let v11 = pair(a11, b11, ux + uz, fx + fz, p2, r2, q2, prm.n2, prm.m2);
    let v13 = pair(a13, b13, ux - uz, fx - fz, p2, r2, q2, prm.n2, prm.m2);
    let v15 = pair(a15, b15, uy + uz, fy + fz, p2, r2, q2, prm.n2, prm.m2);
    let v17 = pair(a17, b17, uy - uz, fy - fz, p2, r2, q2, prm.n2, prm.m2);
    if ODD {
        f1[p + o1] = v1.x;
        f2[p - o1] = v1.y;
        f3[p + o3] = v3.x;
        f4[p - o3] = v3.y;
        f5[p + o5] = v5.x;
        f6[p - o5] = v5.y;
        f7[p + o7] = v7.x;
        f8[p - o7] = v7.y;
        f9[p + o9] = v9.x;
        f10[p - o9] = v9.y;
        f11[p + o11] = v11.x;
        f12[p - o11] = v11.y;
        f13[p + o13] = v13.x;
        f14[p - o13] = v13.y;
        f15[p + o15] = v15.x;
        f16[p - o15] = v15.y;
        f17[p + o17] = v17.x;
        f18[p - o17] = v17.y;
    } else {
        f2[p] = v1.x;
        f1[p] = v1.y;
        f4[p] = v3.x;
        f3[p] = v3.y;
        f6[p] = v5.x;
        f5[p] = v5.y;
        f8[p] = v7.x;
        f7[p] = v7.y;
        f10[p] = v9.x;
        f9[p] = v9.y;
        f12[p] = v11.x;
        f11[p] = v11.y;
        f14[p] = v13.x;
        f13[p] = v13.y;
        f16[p] = v15.x;
        f15[p] = v15.y;
        f18[p] = v17.x;
        f17[p] = v17.y;
    }
}
