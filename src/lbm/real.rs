//! Storage precision and the lane abstraction the collision operators are written in.
//!
//! The collision arithmetic is written once, generically over [`Lane`]: a scalar (`f32`,
//! `f64`) or a short array of them ([`V`]). The fused kernel runs it on `V<T, L>` so that
//! LLVM emits one vector instruction per operation; the reference kernel and row tails run it
//! on scalars. Every lane performs the same IEEE operations in the same order, so vector and
//! scalar results are bitwise equal (no fused multiply-add is used anywhere: Rust never
//! contracts `a * b + c` on its own).

use super::kernel::Planes;
use std::fmt::{Debug, Display};
use std::ops::{Add, AddAssign, Div, Mul, Neg, Sub};

/// A floating-point storage type for populations: `f32` or `f64`. Each also carries the fused
/// kernel's per-precision dispatch (`kernel::Planes`, internal), so `T: Real` is the whole bound a
/// solver type needs.
pub trait Real:
    Lane<S = Self>
    + Planes
    + Copy
    + Send
    + Sync
    + Default
    + Debug
    + Display
    + PartialOrd
    + 'static
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
{
    /// `"f32"` or `"f64"`.
    const NAME: &'static str;
    /// Zero.
    const ZERO: Self;
    /// Conversion from `f64` (rounding to nearest for `f32`).
    fn from_f64(v: f64) -> Self;
    /// Exact widening to `f64`.
    fn to_f64(self) -> f64;
    /// Whether the value is neither infinite nor NaN.
    fn is_finite(self) -> bool;
}

/// Arithmetic on one value or on a bundle of lanes, element-wise.
pub trait Lane:
    Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Div<Output = Self> + Neg<Output = Self>
{
    /// The scalar type of each lane.
    type S: Real;
    /// All lanes set to `s`.
    fn splat(s: Self::S) -> Self;
    /// `self · a + b`, rounded once (fused multiply-add). Every implementation rounds
    /// exactly like `f64::mul_add`, so all kernels agree bitwise.
    fn fma(self, a: Self, b: Self) -> Self;
    /// `self · a − b`, rounded once.
    fn fms(self, a: Self, b: Self) -> Self;
}

/// `Real` and scalar `Lane` for a primitive float type.
macro_rules! scalar {
    ($t:ty, $name:literal) => {
        impl Real for $t {
            const NAME: &'static str = $name;
            const ZERO: Self = 0.0;
            #[inline(always)]
            fn from_f64(v: f64) -> Self {
                v as $t
            }
            #[inline(always)]
            fn to_f64(self) -> f64 {
                self as f64
            }
            #[inline(always)]
            fn is_finite(self) -> bool {
                <$t>::is_finite(self)
            }
        }

        impl Lane for $t {
            type S = $t;
            #[inline(always)]
            fn splat(s: $t) -> Self {
                s
            }
            #[inline(always)]
            fn fma(self, a: Self, b: Self) -> Self {
                self.mul_add(a, b)
            }
            #[inline(always)]
            fn fms(self, a: Self, b: Self) -> Self {
                self.mul_add(a, -b)
            }
        }
    };
}
scalar!(f64, "f64");
scalar!(f32, "f32");

/// `L` lanes of `T`, operated on element-wise. Written as plain loops over a fixed-size
/// array, which LLVM turns into vector instructions once inlined into a function compiled
/// for a wide instruction set.
#[derive(Clone, Copy, Debug)]
#[repr(transparent)]
pub struct V<T, const L: usize>(pub [T; L]);

impl<T: Real, const L: usize> V<T, L> {
    /// Loads `L` consecutive values.
    ///
    /// # Safety
    /// `p .. p + L` must be valid for reads.
    #[inline(always)]
    pub unsafe fn load(p: *const T) -> Self {
        V(std::ptr::read_unaligned(p as *const [T; L]))
    }

    /// Stores `L` consecutive values.
    ///
    /// # Safety
    /// `p .. p + L` must be valid for writes.
    #[inline(always)]
    pub unsafe fn store(self, p: *mut T) {
        std::ptr::write_unaligned(p as *mut [T; L], self.0)
    }
}

macro_rules! lane_binop {
    ($tr:ident, $f:ident, $op:tt) => {
        #[allow(clippy::assign_op_pattern)]
        impl<T: Real, const L: usize> $tr for V<T, L> {
            type Output = Self;
            #[inline(always)]
            fn $f(self, o: Self) -> Self {
                let mut r = self.0;
                for l in 0..L {
                    r[l] = r[l] $op o.0[l];
                }
                V(r)
            }
        }
    };
}
lane_binop!(Add, add, +);
lane_binop!(Sub, sub, -);
lane_binop!(Mul, mul, *);
lane_binop!(Div, div, /);

impl<T: Real, const L: usize> Neg for V<T, L> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        let mut r = self.0;
        for v in r.iter_mut() {
            *v = -*v;
        }
        V(r)
    }
}

impl<T: Real, const L: usize> Lane for V<T, L> {
    type S = T;
    #[inline(always)]
    fn splat(s: T) -> Self {
        V([s; L])
    }
    #[inline(always)]
    fn fma(self, a: Self, b: Self) -> Self {
        let mut r = self.0;
        for l in 0..L {
            r[l] = r[l].fma(a.0[l], b.0[l]);
        }
        V(r)
    }
    #[inline(always)]
    fn fms(self, a: Self, b: Self) -> Self {
        let mut r = self.0;
        for l in 0..L {
            r[l] = r[l].fms(a.0[l], b.0[l]);
        }
        V(r)
    }
}
