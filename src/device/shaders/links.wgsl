// The link operations of the box faces and obstacles, one thread per link: the device's copy
// of `Fluid::apply_links` (src/lbm/fluid.rs). Each link joins a slot of a fluid node (`own`)
// to the slot that the odd sweep reads from or writes to across a face or into an obstacle
// (`ghost`):
// - pre (after the even sweep): f[ghost] = f[own] (+ term for a wall or obstacle);
// - post (after the odd sweep): f[own] = f[ghost] (+ term).
// Every slot is the target of at most one link per phase, and no target is a source in the
// same phase, so the links may run in any order.
//
// Preceded by common.wgsl (bindings, Params, WG).

// Before the odd sweep (true) or after it (false): fixed when the pipeline is made.
override PRE: bool = true;

// Slot n of direction q.
fn load(q: u32, n: u32) -> real {
    switch q {
        case 0u: { return f0[n]; }
        case 1u: { return f1[n]; }
        case 2u: { return f2[n]; }
        case 3u: { return f3[n]; }
        case 4u: { return f4[n]; }
        case 5u: { return f5[n]; }
        case 6u: { return f6[n]; }
        case 7u: { return f7[n]; }
        case 8u: { return f8[n]; }
        case 9u: { return f9[n]; }
        case 10u: { return f10[n]; }
        case 11u: { return f11[n]; }
        case 12u: { return f12[n]; }
        case 13u: { return f13[n]; }
        case 14u: { return f14[n]; }
        case 15u: { return f15[n]; }
        case 16u: { return f16[n]; }
        case 17u: { return f17[n]; }
        case 18u: { return f18[n]; }
        default: { return 0.0; }
    }
}

// Slot n of direction q set to v.
fn store(q: u32, n: u32, v: real) {
    switch q {
        case 0u: { f0[n] = v; }
        case 1u: { f1[n] = v; }
        case 2u: { f2[n] = v; }
        case 3u: { f3[n] = v; }
        case 4u: { f4[n] = v; }
        case 5u: { f5[n] = v; }
        case 6u: { f6[n] = v; }
        case 7u: { f7[n] = v; }
        case 8u: { f8[n] = v; }
        case 9u: { f9[n] = v; }
        case 10u: { f10[n] = v; }
        case 11u: { f11[n] = v; }
        case 12u: { f12[n] = v; }
        case 13u: { f13[n] = v; }
        case 14u: { f14[n] = v; }
        case 15u: { f15[n] = v; }
        case 16u: { f16[n] = v; }
        case 17u: { f17[n] = v; }
        case 18u: { f18[n] = v; }
        default: {}
    }
}

@compute @workgroup_size(WG)
fn apply_links(@builtin(global_invocation_id) gid: vec3<u32>) {
    // Two-dimensional dispatch (a dimension holds at most 65535 groups).
    let k = gid.x + gid.y * prm.link_row;
    if k >= prm.n_links {
        return;
    }
    let l = links[k];
    let own_q = l.dirs & 31u;
    let ghost_q = (l.dirs >> 8u) & 31u;
    let periodic = (l.dirs >> 16u) != 0u;
    let term = l.term;
    if PRE {
        var v = load(own_q, l.own);
        if !periodic {
            v = v + term;
        }
        store(ghost_q, l.ghost, v);
    } else {
        var v = load(ghost_q, l.ghost);
        if !periodic {
            v = v + term;
        }
        store(own_q, l.own, v);
    }
}
