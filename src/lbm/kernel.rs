//! The fused stream–collide kernel: AA pattern, structure of arrays, one lattice, in place.
//!
//! **Storage.** `f[q·stride + n]` holds the shifted population `h_q` of padded node `n` (see
//! [`super::fluid`] for the padded grid with one ghost layer). Each of the 19 arrays starts
//! `stride` elements after the previous one; `stride` is padded so the arrays are not a power
//! of two apart (cache-set conflicts).
//!
//! **AA pattern** (Bailey et al. 2009). Two kinds of step alternate:
//! - *even*: node `x` reads `h_i` from its own slot `(x, i)`, collides, and writes `h_i*` to
//!   its own slot `(x, ī)`. Purely local.
//! - *odd*: node `x` reads `h_i` from `(x − c_i, ī)`, collides, and writes `h_i*` to
//!   `(x + c_i, i)`. The set of slots node `x` reads equals the set it writes, and the sets of
//!   distinct nodes are disjoint: the update is in place and race-free, so any partition
//!   over threads gives bitwise the same result.
//!
//! After an odd step the array is in the standard layout (`(x, i)` holds `h_i(x)`); after an
//! even step `h_i(x)` is found at `(x − c_i, ī)`.
//!
//! **Vectorisation.** A row of nodes is processed `L` at a time: all 19 populations are
//! loaded as [`V<T, L>`] bundles, collided lane-wise, and stored. The row functions are
//! `#[inline(always)]` so that they compile inside the `#[target_feature]` entry points
//! chosen at run time ([`Isa`]). Rows that contain obstacle nodes take a scalar path that
//! skips them. The arithmetic is the same on every path, so results are bitwise identical
//! across instruction sets, lane counts and thread counts.

use super::collision::{collide, Pops, Rates};
#[allow(unused_imports)]
use super::real::{Lane, Real, V};
#[cfg(target_arch = "x86_64")]
use super::simd::{F32x16, F32x4, F32x8, F64x2, F64x4, F64x8};
use crate::lattice::{OPP, Q};

/// Raw view of the solver's arrays for one kernel sweep (internal; public only because
/// [`Planes`] names it).
#[doc(hidden)]
#[allow(missing_docs)]
pub struct Sweep<T> {
    pub f: *mut T,
    /// Force density field, `3·stride` values, or null when the field is off.
    pub force: *const T,
    pub stride: usize,
    /// Padded-grid offset of `c_i`: `c_x + px (c_y + py c_z)`.
    pub off: [isize; Q],
    pub rates: Rates<T>,
    pub body: [T; 3],
    /// Padded-grid row length `px = nx + 2` and rows per plane `py = ny + 2`.
    pub px: usize,
    pub py: usize,
    pub nx: usize,
    pub ny: usize,
    /// Per interior row `(y, z)`: whether it holds obstacle nodes (then `solid` is read).
    pub row_has_solid: *const bool,
    pub solid: *const bool,
}

// SAFETY: the sweep is shared between rayon workers that touch disjoint slot sets (see the
// module docs); the pointers outlive the sweep.
unsafe impl<T: Send> Send for Sweep<T> {}
unsafe impl<T: Sync> Sync for Sweep<T> {}

/// Load/store for a lane bundle or a scalar.
#[doc(hidden)]
#[allow(missing_docs)]
pub trait Chunk: Lane {
    unsafe fn ld(p: *const Self::S) -> Self;
    unsafe fn st(self, p: *mut Self::S);
}

impl<T: Real, const L: usize> Chunk for V<T, L> {
    #[inline(always)]
    unsafe fn ld(p: *const T) -> Self {
        V::load(p)
    }
    #[inline(always)]
    unsafe fn st(self, p: *mut T) {
        self.store(p)
    }
}

macro_rules! scalar_chunk {
    ($t:ty) => {
        impl Chunk for $t {
            #[inline(always)]
            unsafe fn ld(p: *const $t) -> Self {
                *p
            }
            #[inline(always)]
            unsafe fn st(self, p: *mut $t) {
                *p = self
            }
        }
    };
}
scalar_chunk!(f32);
scalar_chunk!(f64);

/// Base pointers of one row for the 19 reads, plus the force field. Kept in locals so that
/// LLVM can see that the population stores do not clobber them. Writes need no pointers of
/// their own: in both sweeps population `i` is written to the slot that `ī` was read from
/// (even: `(x, ī)`; odd: `(x + c_i, i) = (x − c_ī, i)`), so `wr[i] = rd[ī]`.
struct Row<T> {
    rd: [*mut T; Q],
    force: [*const T; 3],
}

/// The populations of the nodes `x .. x + width(K)` of a row, read and written in place.
struct At<'a, K: Chunk> {
    row: &'a Row<K::S>,
    x: usize,
}

impl<K: Chunk> Pops<K> for At<'_, K> {
    #[inline(always)]
    fn get(&self, i: usize) -> K {
        // SAFETY: the row pointers address valid slots for x in 0..nx (padded grid).
        unsafe { K::ld(self.row.rd[i].add(self.x)) }
    }
    #[inline(always)]
    fn set(&mut self, i: usize, v: K) {
        // SAFETY: as above; the slots written for pair (i, ī) are the ones read for it.
        unsafe { v.st(self.row.rd[OPP[i]].add(self.x)) }
    }
}

/// Updates the `width(K)` consecutive nodes starting `x` nodes into the row.
#[inline(always)]
unsafe fn nodes<K: Chunk, const TRT: bool, const FF: bool>(
    r: &Row<K::S>,
    x: usize,
    body: &[K::S; 3],
    rates: &Rates<K::S>,
) {
    let force = if FF {
        [
            K::ld(r.force[0].add(x)) + K::splat(body[0]),
            K::ld(r.force[1].add(x)) + K::splat(body[1]),
            K::ld(r.force[2].add(x)) + K::splat(body[2]),
        ]
    } else {
        [K::splat(body[0]), K::splat(body[1]), K::splat(body[2])]
    };
    collide::<K, _, TRT>(&mut At { row: r, x }, force, rates);
}

/// Updates every fluid node of interior plane `z` (0-based).
#[inline(always)]
unsafe fn plane<T: Real + Chunk<S = T>, K: Chunk<S = T>, const ODD: bool, const TRT: bool, const FF: bool>(
    s: &Sweep<T>,
    z: usize,
) {
    let width = std::mem::size_of::<K>() / std::mem::size_of::<T>();
    let (f, stride, off, nx, ny, px, py) = (s.f, s.stride, s.off, s.nx, s.ny, s.px, s.py);
    let rates = s.rates;
    let body = s.body;
    for y in 0..ny {
        let start = 1 + px * ((y + 1) + py * (z + 1));
        let row = Row {
            rd: std::array::from_fn(|i| {
                if ODD {
                    f.add(OPP[i] * stride).offset(start as isize - off[i])
                } else {
                    f.add(i * stride + start)
                }
            }),
            force: if FF {
                std::array::from_fn(|a| s.force.add(a * stride + start))
            } else {
                [std::ptr::null(); 3]
            },
        };
        if *s.row_has_solid.add(y + ny * z) {
            let solid = s.solid.add(start);
            for x in 0..nx {
                if !*solid.add(x) {
                    nodes::<T, TRT, FF>(&row, x, &body, &rates);
                }
            }
            continue;
        }
        let mut x = 0;
        while x + width <= nx {
            nodes::<K, TRT, FF>(&row, x, &body, &rates);
            x += width;
        }
        while x < nx {
            nodes::<T, TRT, FF>(&row, x, &body, &rates);
            x += 1;
        }
    }
}

/// Instruction set used by the fused kernel, detected at run time.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Isa {
    /// Baseline x86-64 (SSE2) or a non-x86 target.
    Generic,
    /// AVX2 with FMA available (256-bit vectors).
    Avx2,
    /// AVX-512F (512-bit vectors).
    Avx512,
}

impl Isa {
    /// The widest instruction set this CPU supports, unless the environment variable
    /// `SLURRY_ISA` (`generic`, `avx2`, `avx512`) asks for a narrower one.
    pub fn detect() -> Isa {
        let best = Self::best();
        match std::env::var("SLURRY_ISA").as_deref() {
            Ok("generic") => Isa::Generic,
            Ok("avx2") if best != Isa::Generic => Isa::Avx2,
            Ok("avx512") if best == Isa::Avx512 => Isa::Avx512,
            _ => best,
        }
    }

    fn best() -> Isa {
        #[cfg(target_arch = "x86_64")]
        {
            if std::is_x86_feature_detected!("avx512f") {
                return Isa::Avx512;
            }
            if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") {
                return Isa::Avx2;
            }
        }
        Isa::Generic
    }

    /// Every instruction set this CPU can run, narrowest first (for equivalence tests).
    pub fn available() -> Vec<Isa> {
        let best = Self::best();
        [Isa::Generic, Isa::Avx2, Isa::Avx512].into_iter().filter(|&i| i as u8 <= best as u8).collect()
    }

    /// Short name.
    pub fn name(self) -> &'static str {
        match self {
            Isa::Generic => "generic",
            Isa::Avx2 => "avx2",
            Isa::Avx512 => "avx512",
        }
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn plane_avx2<
    T: Real + Chunk<S = T>,
    K: Chunk<S = T>,
    const ODD: bool,
    const TRT: bool,
    const FF: bool,
>(
    s: &Sweep<T>,
    z: usize,
) {
    plane::<T, K, ODD, TRT, FF>(s, z)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx2,fma")]
unsafe fn plane_avx512<
    T: Real + Chunk<S = T>,
    K: Chunk<S = T>,
    const ODD: bool,
    const TRT: bool,
    const FF: bool,
>(
    s: &Sweep<T>,
    z: usize,
) {
    plane::<T, K, ODD, TRT, FF>(s, z)
}

/// Per-precision choice of lane counts; implemented for `f32` and `f64`. A supertrait of
/// [`Real`], so that a bound outside `lbm` names `T: Real` alone (this trait is the kernel's
/// concern, not the caller's).
#[doc(hidden)]
pub trait Planes: Sized {
    /// Updates plane `z` with the kernel for `isa`.
    ///
    /// # Safety
    /// `s` must describe valid arrays for the padded grid, and no other thread may touch the
    /// slots of this plane's nodes during the call.
    unsafe fn plane<const ODD: bool, const TRT: bool, const FF: bool>(isa: Isa, s: &Sweep<Self>, z: usize);
}

macro_rules! planes {
    ($t:ty, $generic:ty, $avx2:ty, $avx512:ty) => {
        impl Planes for $t {
            #[inline]
            unsafe fn plane<const ODD: bool, const TRT: bool, const FF: bool>(
                isa: Isa,
                s: &Sweep<$t>,
                z: usize,
            ) {
                match isa {
                    #[cfg(target_arch = "x86_64")]
                    Isa::Avx512 => plane_avx512::<$t, $avx512, ODD, TRT, FF>(s, z),
                    #[cfg(target_arch = "x86_64")]
                    Isa::Avx2 => plane_avx2::<$t, $avx2, ODD, TRT, FF>(s, z),
                    _ => plane::<$t, $generic, ODD, TRT, FF>(s, z),
                }
            }
        }
    };
}
#[cfg(target_arch = "x86_64")]
planes!(f64, F64x2, F64x4, F64x8);
#[cfg(target_arch = "x86_64")]
planes!(f32, F32x4, F32x8, F32x16);
#[cfg(not(target_arch = "x86_64"))]
planes!(f64, V<f64, 2>, V<f64, 4>, V<f64, 8>);
#[cfg(not(target_arch = "x86_64"))]
planes!(f32, V<f32, 4>, V<f32, 8>, V<f32, 16>);

/// Runs one sweep (even or odd) over all interior planes, in parallel with rayon.
pub(crate) fn sweep<T: Real>(isa: Isa, s: &Sweep<T>, nz: usize, odd: bool, trt: bool, ff: bool) {
    use rayon::prelude::*;
    macro_rules! go {
        ($o:literal, $t:literal, $f:literal) => {
            (0..nz).into_par_iter().for_each(|z| unsafe { T::plane::<$o, $t, $f>(isa, s, z) })
        };
    }
    match (odd, trt, ff) {
        (false, false, false) => go!(false, false, false),
        (false, false, true) => go!(false, false, true),
        (false, true, false) => go!(false, true, false),
        (false, true, true) => go!(false, true, true),
        (true, false, false) => go!(true, false, false),
        (true, false, true) => go!(true, false, true),
        (true, true, false) => go!(true, true, false),
        (true, true, true) => go!(true, true, true),
    }
}
