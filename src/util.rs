//! Small utilities shared by the modules, tests, verification cases and benchmarks: seeded
//! random numbers, compensated sums, integer floor and ceil, number formatting, the observed
//! order and Richardson estimate of three resolutions ([`richardson3`]), and [`SharedMut`],
//! the one shared mutable slice of the parallel phases.

/// SplitMix64 (Steele, Lea & Flood 2014): a tiny, seeded, portable pseudo-random generator.
/// Used wherever a test or verification case needs reproducible random input; it is not for
/// anything statistical beyond that.
#[derive(Clone, Debug)]
pub struct SplitMix64(pub u64);

impl SplitMix64 {
    /// Next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `[0, 1)`, 53 random bits.
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in `[lo, hi)`.
    pub fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }

    /// Three independent draws uniform in `[lo, hi)`.
    pub fn vec3(&mut self, lo: f64, hi: f64) -> [f64; 3] {
        [self.uniform(lo, hi), self.uniform(lo, hi), self.uniform(lo, hi)]
    }
}

/// Neumaier's compensated sum: the result carries (almost) no round-off of its own, so that a
/// measured defect (e.g. of an adjoint pair) is the operators' and not the summation's.
pub fn compensated_sum(values: impl Iterator<Item = f64>) -> f64 {
    let (mut s, mut c) = (0.0f64, 0.0f64);
    for v in values {
        let t = s + v;
        c += if s.abs() >= v.abs() { (s - t) + v } else { (v - t) + s };
        s = t;
    }
    s + c
}

/// `⌊x⌋` as an integer, without a call: the default x86-64 target has no SSE4.1 `roundsd`, so
/// `f64::floor` is a libm call (≈ 2 % of the coupled step in the stencil and band builders).
/// Exact: the same integer as `x.floor() as i64` for every `x`, including the saturating cases
/// (`NaN` → 0, `±∞` and beyond `±2⁶³` → `i64::MIN`/`MAX`).
#[inline(always)]
pub fn floor_i64(x: f64) -> i64 {
    let t = x as i64; // truncation toward zero (saturating)
    if (t as f64) > x {
        t.saturating_sub(1)
    } else {
        t
    }
}

/// `⌈x⌉` as an integer, without a call ([`floor_i64`]): the same integer as `x.ceil() as i64`.
#[inline(always)]
pub fn ceil_i64(x: f64) -> i64 {
    let t = x as i64;
    if (t as f64) < x {
        t.saturating_add(1)
    } else {
        t
    }
}

/// A mutable slice shared by the tasks of one parallel loop, each of which writes its own
/// indices: the one pointer wrapper the parallel phases use where safe Rust cannot split the
/// slice (the fluid's link operations and force-field writer, the IBM spreading, the band
/// velocity per z-plane).
///
/// Made from a `&'a mut [T]` and holding that borrow for `'a`, so the slice outlives every
/// task and nothing else touches it meanwhile. It is `Sync`, so `&SharedMut` may be handed to
/// every task; its accesses are `unsafe` because the compiler cannot see the partition.
///
/// **Safety contract** (what every caller of [`SharedMut::read`] and [`SharedMut::write`]
/// upholds, each at its call with a `SAFETY` comment naming the partition):
/// - each index is in bounds (checked only in debug builds);
/// - each task writes indices disjoint from those every other task writes or reads during the
///   parallel phase (e.g. the nodes of its own z-plane or slab, or the targets of its own
///   links);
/// - reads do not race with writes: an index read by one task is written by no other task in
///   the same phase (concurrent reads of one index are fine).
///
/// Under this contract the values written do not depend on the schedule, so results are
/// bitwise the same for any thread count.
pub struct SharedMut<'a, T> {
    ptr: *mut T,
    len: usize,
    _borrow: std::marker::PhantomData<&'a mut [T]>,
}

// SAFETY: a `SharedMut` is a mutable borrow of the slice; sending it, or sharing it between
// threads, moves and copies `T` values between threads (hence `T: Send + Sync`), and every
// access is `unsafe`, with the contract above excluding data races.
unsafe impl<T: Send + Sync> Send for SharedMut<'_, T> {}
unsafe impl<T: Send + Sync> Sync for SharedMut<'_, T> {}

impl<'a, T> SharedMut<'a, T> {
    /// Shares `slice` for the tasks of one parallel phase (see the safety contract above).
    pub fn new(slice: &'a mut [T]) -> Self {
        Self { ptr: slice.as_mut_ptr(), len: slice.len(), _borrow: std::marker::PhantomData }
    }

    /// The slice's length.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether the slice is empty.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// `slice[i]`.
    ///
    /// # Safety
    /// `i < self.len()`, and no other task writes index `i` during the parallel phase.
    #[inline(always)]
    pub unsafe fn read(&self, i: usize) -> T
    where
        T: Copy,
    {
        debug_assert!(i < self.len);
        *self.ptr.add(i)
    }

    /// A hint that `slice[i]` will soon be read and written ([`prefetch`]); nothing for an
    /// index past the end.
    #[inline(always)]
    pub fn prefetch(&self, i: usize) {
        if i < self.len {
            prefetch(self.ptr.wrapping_add(i).cast_const());
        }
    }

    /// `slice[i] = v`.
    ///
    /// # Safety
    /// `i < self.len()`, and no other task reads or writes index `i` during the parallel phase.
    #[inline(always)]
    pub unsafe fn write(&self, i: usize, v: T) {
        debug_assert!(i < self.len);
        *self.ptr.add(i) = v;
    }
}

/// A hint to the processor to bring the cache line holding `p` into its nearest cache, for a
/// read or update that follows soon (a software prefetch, `prefetcht0` on x86-64; nothing on
/// other targets). It never faults and changes no value, only when memory is fetched: for the
/// scattered accesses of the immersed boundary, whose next rows the hardware prefetchers
/// cannot guess.
#[inline(always)]
pub fn prefetch<T>(p: *const T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch is only a hint: it does not dereference `p` (any address, even an
    // invalid one, is allowed and does not fault).
    unsafe {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        _mm_prefetch::<_MM_HINT_T0>(p.cast::<i8>());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = p;
}

/// The observed order `p` and the Richardson estimate `f₀` of a quantity `f` computed at three
/// grid spacings `h₀ > h₁ > h₂` (any ratios), assuming `f(h) = f₀ + C hᵖ`:
///
/// ```text
/// (f[0] − f[1])/(f[1] − f[2]) = (h₀ᵖ − h₁ᵖ)/(h₁ᵖ − h₂ᵖ)     (solved for p by bisection on (0.05, 8))
/// f₀ = f₂ − (f₁ − f₂)/((h₁/h₂)ᵖ − 1)
/// ```
///
/// `None` when the spacings do not strictly decrease to a positive finite value, when the
/// sequence is not monotone (the differences change sign), or when no `p` in the bracket
/// fits: then no order can be claimed from these three points.
pub fn richardson3(h: [f64; 3], f: [f64; 3]) -> Option<(f64, f64)> {
    if !(h[0].is_finite() && h[0] > h[1] && h[1] > h[2] && h[2] > 0.0) {
        return None;
    }
    let (d01, d12) = (f[0] - f[1], f[1] - f[2]);
    if d01 == 0.0 || d12 == 0.0 || d01.signum() != d12.signum() {
        return None;
    }
    let target = d01 / d12;
    let ratio = |p: f64| (h[0].powf(p) - h[1].powf(p)) / (h[1].powf(p) - h[2].powf(p));
    let (mut lo, mut hi) = (0.05, 8.0);
    // `ratio` increases with p for decreasing spacings.
    if !(ratio(lo) <= target && target <= ratio(hi)) {
        return None;
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if ratio(mid) < target {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let p = 0.5 * (lo + hi);
    Some((p, f[2] - d12 / ((h[1] / h[2]).powf(p) - 1.0)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn richardson3_recovers_order_and_limit_for_unequal_ratios() {
        let h = [4.0, 3.0, 2.0];
        for p in [0.7, 1.0, 2.0] {
            let f = h.map(|v: f64| 2.5 + 0.3 * v.powf(p));
            let (q, f0) = richardson3(h, f).unwrap();
            assert!((q - p).abs() < 1e-9 && (f0 - 2.5).abs() < 1e-9, "p {p}: got {q}, {f0}");
        }
        assert!(richardson3(h, [1.0, 2.0, 1.5]).is_none(), "non-monotone");
        assert!(richardson3([2.0, 3.0, 4.0], [1.0, 2.0, 3.0]).is_none(), "spacings increasing");
        assert!(richardson3([f64::INFINITY, 3.0, 2.0], [1.0, 2.0, 3.0]).is_none(), "infinite spacing");
    }

    #[test]
    fn shared_mut_tasks_write_disjoint_indices() {
        use rayon::prelude::*;
        let mut v = vec![0u64; 1000];
        let shared = SharedMut::new(&mut v);
        assert_eq!(shared.len(), 1000);
        // SAFETY: task i writes index i only and reads nothing another task writes.
        (0..1000usize).into_par_iter().for_each(|i| unsafe { shared.write(i, shared.read(i) + i as u64) });
        assert!(v.iter().enumerate().all(|(i, &x)| x == i as u64));
    }

    #[test]
    fn floor_and_ceil_match_std() {
        let mut rng = SplitMix64(7);
        let special = [
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            1e-300,
            -1e-300,
            2.5,
            -2.5,
            4503599627370495.5,
            -4503599627370495.5,
            9.3e18,
            -9.3e18,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            f64::MAX,
            f64::MIN,
        ];
        let random = (0..100_000).map(|k| rng.uniform(-300.0, 300.0) * if k % 3 == 0 { 1e-3 } else { 1.0 });
        for x in special.into_iter().chain(random) {
            assert_eq!(floor_i64(x), x.floor() as i64, "floor {x}");
            assert_eq!(ceil_i64(x), x.ceil() as i64, "ceil {x}");
        }
        for k in -1000i64..1000 {
            let x = k as f64;
            assert_eq!((floor_i64(x), ceil_i64(x)), (k, k));
        }
    }

    #[test]
    fn compensated_sum_recovers_what_plain_summation_loses() {
        let v = [1.0, 1e100, 1.0, -1e100];
        assert_eq!(v.iter().sum::<f64>(), 0.0);
        assert_eq!(compensated_sum(v.into_iter()), 2.0);
    }

    #[test]
    fn draws_are_in_range_and_seeded() {
        let (mut a, mut b) = (SplitMix64(7), SplitMix64(7));
        for _ in 0..1000 {
            let x = a.uniform(-2.0, 3.0);
            assert!((-2.0..3.0).contains(&x));
            assert_eq!(x.to_bits(), b.uniform(-2.0, 3.0).to_bits());
        }
    }
}

/// `x` for people: rounded to 12 significant digits, then in the shortest form that reads
/// back as that rounded value (`2.4000000000000004` → `2.4`, `0.1 + 0.2` → `0.3`; integers
/// and short decimals are unchanged, non-finite values print as Rust prints them).
pub fn fmt_num(x: f64) -> String {
    if !x.is_finite() || x == 0.0 {
        return format!("{x}");
    }
    let rounded: f64 = format!("{x:.11e}").parse().unwrap_or(x);
    let a = rounded.abs();
    if (1e-5..1e15).contains(&a) {
        format!("{rounded}")
    } else {
        format!("{rounded:e}")
    }
}

/// `text` with every decimal number that has more than 12 significant digits (a computed
/// limit like `2.4000000000000004`) replaced by [`fmt_num`] of it; everything else, integers
/// included, is left as it is.
pub fn humanize_numbers(text: &str) -> String {
    let bytes = text.as_bytes();
    let mut out = String::with_capacity(text.len());
    let mut i = 0;
    while i < bytes.len() {
        let starts_number = bytes[i].is_ascii_digit()
            && (i == 0 || !(bytes[i - 1].is_ascii_alphanumeric() || bytes[i - 1] == b'_'));
        if !starts_number {
            let ch = text[i..].chars().next().unwrap_or(' ');
            out.push(ch);
            i += ch.len_utf8();
            continue;
        }
        let mut j = i;
        while j < bytes.len() && bytes[j].is_ascii_digit() {
            j += 1;
        }
        if j + 1 < bytes.len() && bytes[j] == b'.' && bytes[j + 1].is_ascii_digit() {
            j += 1;
            while j < bytes.len() && bytes[j].is_ascii_digit() {
                j += 1;
            }
            // An exponent, if any.
            if j + 1 < bytes.len() && (bytes[j] == b'e' || bytes[j] == b'E') {
                let mut k = j + 1;
                if k < bytes.len() && (bytes[k] == b'-' || bytes[k] == b'+') {
                    k += 1;
                }
                if k < bytes.len() && bytes[k].is_ascii_digit() {
                    while k < bytes.len() && bytes[k].is_ascii_digit() {
                        k += 1;
                    }
                    j = k;
                }
            }
            let token = &text[i..j];
            let mantissa = token.split(['e', 'E']).next().unwrap_or(token);
            let digits = mantissa.trim_start_matches(['0', '.']).chars().filter(char::is_ascii_digit).count();
            match token.parse::<f64>() {
                Ok(v) if digits > 12 => out.push_str(&fmt_num(v)),
                _ => out.push_str(token),
            }
        } else {
            out.push_str(&text[i..j]);
        }
        i = j;
    }
    out
}

#[cfg(test)]
mod fmt_tests {
    use super::*;

    #[test]
    fn numbers_for_people() {
        assert_eq!(fmt_num(2.4000000000000004), "2.4");
        assert_eq!(fmt_num(0.1 + 0.2), "0.3");
        assert_eq!(fmt_num(1e-300), "1e-300");
        assert_eq!(fmt_num(12.0), "12");
        assert_eq!(fmt_num(0.1875), "0.1875");
        assert_eq!(
            humanize_numbers("0 < shaft_diameter < 2.4000000000000004 (hub 2.4), 18446744073709551615"),
            "0 < shaft_diameter < 2.4 (hub 2.4), 18446744073709551615"
        );
        assert_eq!(humanize_numbers("x2.4000000000000004 é 1.25"), "x2.4000000000000004 é 1.25");
    }
}
