//! Small numerical utilities shared by tests, verification cases and benchmarks.

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

#[cfg(test)]
mod tests {
    use super::*;

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
