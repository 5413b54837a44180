// Bindings and parameters shared by the fluid kernels (stream_collide.wgsl, links.wgsl).
//
// `real` is the storage precision, f32 or f64: src/device/fluid.rs puts `alias real = f32;` (or
// f64) before this file.
//
// Storage: the shifted populations h_q = f_q - w_q of padded node n in f<q>[n], one binding per
// direction (a binding is limited in size on some drivers), the padded layout of the CPU solver
// (src/lbm/fluid.rs): interior node (x, y, z) at (x+1) + px ((y+1) + py (z+1)).
//
// The kernels run without the shader's own bounds checks: every index is in range by
// construction (src/device/fluid.rs says why), so no access is clamped.

struct Params {
    nx: u32,
    ny: u32,
    nz: u32,
    px: u32,
    py: u32,
    // Number of link operations, and the threads of one row of the link dispatch.
    n_links: u32,
    link_row: u32,
    pad0: u32,
    // Uniform body force.
    body_x: real,
    body_y: real,
    body_z: real,
    // Collision constants, each rounded once from f64 as in src/lbm/collision.rs:
    // omega = w+; sp3 = 3 (1 - w+/2); w0, w1, w2 the weights; r = 9/2 w+ w; q = 3 w- w;
    // n = 9 (1 - w+/2) w; m = 3 (1 - w-/2) w; keep = 1 - w+; hp = w+/2; hm = w-/2.
    omega: real,
    sp3: real,
    w0: real,
    w1: real,
    w2: real,
    r1: real,
    r2: real,
    q1: real,
    q2: real,
    n1: real,
    n2: real,
    m1: real,
    m2: real,
    keep: real,
    hp: real,
    hm: real,
}

@group(0) @binding(0) var<uniform> prm: Params;
@group(0) @binding(1) var<storage, read_write> f0: array<real>;
@group(0) @binding(2) var<storage, read_write> f1: array<real>;
@group(0) @binding(3) var<storage, read_write> f2: array<real>;
@group(0) @binding(4) var<storage, read_write> f3: array<real>;
@group(0) @binding(5) var<storage, read_write> f4: array<real>;
@group(0) @binding(6) var<storage, read_write> f5: array<real>;
@group(0) @binding(7) var<storage, read_write> f6: array<real>;
@group(0) @binding(8) var<storage, read_write> f7: array<real>;
@group(0) @binding(9) var<storage, read_write> f8: array<real>;
@group(0) @binding(10) var<storage, read_write> f9: array<real>;
@group(0) @binding(11) var<storage, read_write> f10: array<real>;
@group(0) @binding(12) var<storage, read_write> f11: array<real>;
@group(0) @binding(13) var<storage, read_write> f12: array<real>;
@group(0) @binding(14) var<storage, read_write> f13: array<real>;
@group(0) @binding(15) var<storage, read_write> f14: array<real>;
@group(0) @binding(16) var<storage, read_write> f15: array<real>;
@group(0) @binding(17) var<storage, read_write> f16: array<real>;
@group(0) @binding(18) var<storage, read_write> f17: array<real>;
@group(0) @binding(19) var<storage, read_write> f18: array<real>;
// Force density field per component (padded layout); a 4-byte placeholder when the field is off.
@group(0) @binding(20) var<storage, read> force_x: array<real>;
@group(0) @binding(21) var<storage, read> force_y: array<real>;
@group(0) @binding(22) var<storage, read> force_z: array<real>;
// One bit per padded node: ghost or obstacle (bit n & 31 of word n >> 5).
@group(0) @binding(23) var<storage, read> solid: array<u32>;
// Link operations: own slot, ghost slot, own direction | ghost direction << 8 | periodic << 16,
// and the wall term.
struct Link {
    own: u32,
    ghost: u32,
    dirs: u32,
    term: real,
}
@group(0) @binding(24) var<storage, read> links: array<Link>;

// Work-group size, set when the pipeline is made.
override WG: u32 = 64u;
