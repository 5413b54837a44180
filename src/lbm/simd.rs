//! Explicit x86-64 vector lanes for the fused kernel.
//!
//! LLVM's automatic re-vectorisation of fixed-size array loops ([`super::real::V`]) split the
//! collision into a mix of 128-bit, scalar and shuffle instructions (measured: 33–44 MLUPS f64
//! instead of ~100 at the bandwidth ceiling). These wrappers map each lane operation to exactly
//! one vector instruction. They are `#[inline(always)]`, and only ever called from inside the
//! `#[target_feature]` entry points in [`super::kernel`], where the intrinsics inline.
//!
//! Everything between the entry point and these operations must inline: a generic helper from
//! `core` (e.g. `std::array::from_fn`) that LLVM leaves out of line is compiled without the
//! entry point's target features, and then calls each intrinsic as a function (measured: 3.5×
//! slower). `cargo xtask bench` checks the binary for such calls.
//!
//! Fused multiply-adds round exactly like the scalar `mul_add`, so every lane computes exactly
//! what the scalar code computes.
#![allow(unsafe_op_in_unsafe_fn)]

#[cfg(target_arch = "x86_64")]
use std::arch::x86_64::*;
use std::ops::{Add, Div, Mul, Neg, Sub};

use super::kernel::Chunk;
use super::real::Lane;

macro_rules! lanes {
    ($name:ident, $t:ty, $reg:ty, $set1:ident, $add:ident, $sub:ident, $mul:ident, $div:ident, $xor:ident, $ld:ident, $st:ident, $fmadd:path, $fmsub:path, $zero:expr, $doc:literal) => {
        #[doc = $doc]
        #[cfg(target_arch = "x86_64")]
        #[derive(Clone, Copy, Debug)]
        #[repr(transparent)]
        pub struct $name($reg);

        #[cfg(target_arch = "x86_64")]
        impl Add for $name {
            type Output = Self;
            #[inline(always)]
            fn add(self, o: Self) -> Self {
                unsafe { $name($add(self.0, o.0)) }
            }
        }
        #[cfg(target_arch = "x86_64")]
        impl Sub for $name {
            type Output = Self;
            #[inline(always)]
            fn sub(self, o: Self) -> Self {
                unsafe { $name($sub(self.0, o.0)) }
            }
        }
        #[cfg(target_arch = "x86_64")]
        impl Mul for $name {
            type Output = Self;
            #[inline(always)]
            fn mul(self, o: Self) -> Self {
                unsafe { $name($mul(self.0, o.0)) }
            }
        }
        #[cfg(target_arch = "x86_64")]
        impl Div for $name {
            type Output = Self;
            #[inline(always)]
            fn div(self, o: Self) -> Self {
                unsafe { $name($div(self.0, o.0)) }
            }
        }
        #[cfg(target_arch = "x86_64")]
        impl Neg for $name {
            type Output = Self;
            /// Sign flip by XOR with −0.0: exactly IEEE negation, like scalar `-x`.
            #[inline(always)]
            fn neg(self) -> Self {
                unsafe { $name($xor(self.0, $set1($zero))) }
            }
        }
        #[cfg(target_arch = "x86_64")]
        impl Lane for $name {
            type S = $t;
            #[inline(always)]
            fn splat(s: $t) -> Self {
                unsafe { $name($set1(s)) }
            }
            #[inline(always)]
            fn fma(self, a: Self, b: Self) -> Self {
                unsafe { $name($fmadd(self.0, a.0, b.0)) }
            }
            #[inline(always)]
            fn fms(self, a: Self, b: Self) -> Self {
                unsafe { $name($fmsub(self.0, a.0, b.0)) }
            }
        }
        #[cfg(target_arch = "x86_64")]
        impl Chunk for $name {
            #[inline(always)]
            unsafe fn ld(p: *const $t) -> Self {
                $name($ld(p))
            }
            #[inline(always)]
            unsafe fn st(self, p: *mut $t) {
                $st(p, self.0)
            }
        }
    };
}

lanes!(
    F64x2,
    f64,
    __m128d,
    _mm_set1_pd,
    _mm_add_pd,
    _mm_sub_pd,
    _mm_mul_pd,
    _mm_div_pd,
    _mm_xor_pd,
    _mm_loadu_pd,
    _mm_storeu_pd,
    sse::fma_pd,
    sse::fms_pd,
    -0.0,
    "Two `f64` lanes (SSE2)."
);
lanes!(
    F32x4,
    f32,
    __m128,
    _mm_set1_ps,
    _mm_add_ps,
    _mm_sub_ps,
    _mm_mul_ps,
    _mm_div_ps,
    _mm_xor_ps,
    _mm_loadu_ps,
    _mm_storeu_ps,
    sse::fma_ps,
    sse::fms_ps,
    -0.0,
    "Four `f32` lanes (SSE2)."
);
lanes!(
    F64x4,
    f64,
    __m256d,
    _mm256_set1_pd,
    _mm256_add_pd,
    _mm256_sub_pd,
    _mm256_mul_pd,
    _mm256_div_pd,
    _mm256_xor_pd,
    _mm256_loadu_pd,
    _mm256_storeu_pd,
    _mm256_fmadd_pd,
    _mm256_fmsub_pd,
    -0.0,
    "Four `f64` lanes (AVX)."
);
lanes!(
    F32x8,
    f32,
    __m256,
    _mm256_set1_ps,
    _mm256_add_ps,
    _mm256_sub_ps,
    _mm256_mul_ps,
    _mm256_div_ps,
    _mm256_xor_ps,
    _mm256_loadu_ps,
    _mm256_storeu_ps,
    _mm256_fmadd_ps,
    _mm256_fmsub_ps,
    -0.0,
    "Eight `f32` lanes (AVX)."
);
lanes!(
    F64x8,
    f64,
    __m512d,
    _mm512_set1_pd,
    _mm512_add_pd,
    _mm512_sub_pd,
    _mm512_mul_pd,
    _mm512_div_pd,
    xor512d,
    _mm512_loadu_pd,
    _mm512_storeu_pd,
    _mm512_fmadd_pd,
    _mm512_fmsub_pd,
    -0.0,
    "Eight `f64` lanes (AVX-512F)."
);
lanes!(
    F32x16,
    f32,
    __m512,
    _mm512_set1_ps,
    _mm512_add_ps,
    _mm512_sub_ps,
    _mm512_mul_ps,
    _mm512_div_ps,
    xor512s,
    _mm512_loadu_ps,
    _mm512_storeu_ps,
    _mm512_fmadd_ps,
    _mm512_fmsub_ps,
    -0.0,
    "Sixteen `f32` lanes (AVX-512F)."
);

/// XOR of `f64` vectors with AVX-512F only (`_mm512_xor_pd` needs AVX-512DQ).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn xor512d(a: __m512d, b: __m512d) -> __m512d {
    _mm512_castsi512_pd(_mm512_xor_si512(_mm512_castpd_si512(a), _mm512_castpd_si512(b)))
}

/// XOR of `f32` vectors with AVX-512F only.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn xor512s(a: __m512, b: __m512) -> __m512 {
    _mm512_castsi512_ps(_mm512_xor_si512(_mm512_castps_si512(a), _mm512_castps_si512(b)))
}

/// Fused multiply-add for the SSE2 fallback, which has no FMA instruction: lane by lane with
/// the correctly rounded `mul_add` (a library call; the fallback is for correctness on CPUs
/// without AVX2/FMA, not for speed).
#[cfg(target_arch = "x86_64")]
mod sse {
    use std::arch::x86_64::*;

    macro_rules! emulate {
        ($name:ident, $reg:ty, $t:ty, $n:literal, $neg:literal) => {
            #[inline(always)]
            pub unsafe fn $name(a: $reg, b: $reg, c: $reg) -> $reg {
                let a = std::mem::transmute::<$reg, [$t; $n]>(a);
                let b = std::mem::transmute::<$reg, [$t; $n]>(b);
                let c = std::mem::transmute::<$reg, [$t; $n]>(c);
                let r: [$t; $n] =
                    std::array::from_fn(|l| a[l].mul_add(b[l], if $neg { -c[l] } else { c[l] }));
                std::mem::transmute::<[$t; $n], $reg>(r)
            }
        };
    }
    emulate!(fma_pd, __m128d, f64, 2, false);
    emulate!(fms_pd, __m128d, f64, 2, true);
    emulate!(fma_ps, __m128, f32, 4, false);
    emulate!(fms_ps, __m128, f32, 4, true);
}
