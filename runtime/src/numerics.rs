//! Log-space arithmetic shared by the interpreter and generated code.
//!
//! Values are natural logarithms; `-∞` stands for probability 0. Every function here
//! is total on `[-∞, +∞)`: `-∞` inputs never produce NaN (all `-∞` → `-∞`), a `+∞`
//! input gives `+∞`, and only a NaN input gives NaN.
//!
//! # Error bound
//!
//! With `ε` the machine epsilon of the type (`f64::EPSILON` or `f32::EPSILON`) and
//! `libm`'s `exp`/`log1p`/`ln` accurate to 1 ulp:
//! - [`log_add_exp`]: `|result − exact| ≤ 3·ε·(1 + |result|)`;
//! - [`log_sum_exp`] over `n` finite-or-`-∞` inputs: `|result − exact| ≤ (n + 3)·ε·(1 + |result|)`.
//!
//! Both are computed as `m + ln(Σ exp(xᵢ − m))` with `m = max xᵢ`: every `exp`
//! argument is ≤ 0, so nothing overflows, the largest term is exactly 1 and the
//! sum lies in `[1, n]`; the `ε·|result|` part is the rounding of the final addition,
//! the constant part bounds the `exp`, summation and `ln` errors (each term's `exp`
//! contributes at most `ε` absolute error to a sum ≥ 1).

/// Log-space addition and reduction for a floating-point type.
pub trait LogSumExp: Copy {
    /// `ln(exp(self) + exp(other))`; see the [module](self) docs for the error bound.
    fn log_add_exp(self, other: Self) -> Self;
    /// `ln(Σ exp(xᵢ))`, `-∞` for an empty slice; see the [module](self) docs for the error bound.
    fn log_sum_exp(xs: &[Self]) -> Self;
}

macro_rules! impl_log_sum_exp {
    ($t:ty, $exp:path, $log1p:path, $ln:path) => {
        impl LogSumExp for $t {
            #[inline]
            fn log_add_exp(self, other: $t) -> $t {
                let (a, b) = (self, other);
                if a.is_nan() || b.is_nan() {
                    return <$t>::NAN;
                }
                let (hi, lo) = if a >= b { (a, b) } else { (b, a) };
                if lo == <$t>::NEG_INFINITY || hi == <$t>::INFINITY {
                    // Covers "both -inf" (→ -inf) without computing -inf - -inf = NaN.
                    return hi;
                }
                hi + $log1p($exp(lo - hi))
            }

            fn log_sum_exp(xs: &[$t]) -> $t {
                let mut m = <$t>::NEG_INFINITY;
                for &x in xs {
                    if x.is_nan() {
                        return <$t>::NAN;
                    }
                    if x > m {
                        m = x;
                    }
                }
                if m == <$t>::NEG_INFINITY || m == <$t>::INFINITY {
                    return m;
                }
                let mut s: $t = 0.0;
                for &x in xs {
                    s += $exp(x - m);
                }
                m + $ln(s)
            }
        }
    };
}

impl_log_sum_exp!(f64, libm::exp, libm::log1p, libm::log);
impl_log_sum_exp!(f32, libm::expf, libm::log1pf, libm::logf);

/// `ln(eᵃ + eᵇ)` in `f64`; `|result − exact| ≤ 3·ε·(1 + |result|)`, never NaN for non-NaN inputs.
#[inline]
pub fn log_add_exp(a: f64, b: f64) -> f64 {
    a.log_add_exp(b)
}

/// `ln(Σ exp(xᵢ))` in `f64`, `-∞` for an empty slice or all `-∞`;
/// `|result − exact| ≤ (n + 3)·ε·(1 + |result|)` for `n = xs.len()`.
#[inline]
pub fn log_sum_exp(xs: &[f64]) -> f64 {
    f64::log_sum_exp(xs)
}

/// `ln(eᵃ + eᵇ)` in `f32`; `|result − exact| ≤ 3·ε·(1 + |result|)` with `ε = f32::EPSILON`.
#[inline]
pub fn log_add_exp_f32(a: f32, b: f32) -> f32 {
    a.log_add_exp(b)
}

/// `ln(Σ exp(xᵢ))` in `f32`, `-∞` for an empty slice or all `-∞`;
/// `|result − exact| ≤ (n + 3)·ε·(1 + |result|)` with `ε = f32::EPSILON`.
#[inline]
pub fn log_sum_exp_f32(xs: &[f32]) -> f32 {
    f32::log_sum_exp(xs)
}

#[cfg(test)]
mod tests {
    use super::*;

    const NINF: f64 = f64::NEG_INFINITY;

    fn bound64(result: f64, n: usize) -> f64 {
        (n as f64 + 3.0) * f64::EPSILON * (1.0 + result.abs())
    }

    #[test]
    fn neg_infinity_inputs_never_nan() {
        assert_eq!(log_add_exp(NINF, NINF), NINF);
        assert_eq!(log_add_exp(NINF, 2.5), 2.5);
        assert_eq!(log_add_exp(-7.0, NINF), -7.0);
        assert_eq!(log_sum_exp(&[]), NINF);
        assert_eq!(log_sum_exp(&[NINF, NINF, NINF]), NINF);
        assert_eq!(log_sum_exp(&[NINF, 1.5, NINF]), 1.5);
        assert_eq!(
            log_add_exp_f32(f32::NEG_INFINITY, f32::NEG_INFINITY),
            f32::NEG_INFINITY
        );
        assert_eq!(log_sum_exp_f32(&[f32::NEG_INFINITY; 4]), f32::NEG_INFINITY);
        assert_eq!(log_add_exp(f64::INFINITY, NINF), f64::INFINITY);
        assert!(log_add_exp(f64::NAN, 0.0).is_nan());
        assert!(log_sum_exp(&[0.0, f64::NAN]).is_nan());
    }

    #[test]
    fn matches_linear_space_within_bound() {
        // Values whose linear-space sum is exactly representable-ish: compare with the
        // direct formula where it is accurate (moderate magnitudes).
        let cases: [(f64, f64); 5] = [
            (0.0, 0.0),
            (-1.0, -2.0),
            (3.0, -4.5),
            (-700.0, -700.5),
            (10.0, 10.0),
        ];
        for (a, b) in cases {
            let exact = libm::log(libm::exp(a) + libm::exp(b));
            let got = log_add_exp(a, b);
            assert!((got - exact).abs() <= bound64(got, 2) + 2.0 * f64::EPSILON * exact.abs());
            assert_eq!(got, log_add_exp(b, a), "symmetric");
        }
        // ln 2 exactly for two zeros.
        assert!((log_add_exp(0.0, 0.0) - core::f64::consts::LN_2).abs() <= bound64(0.7, 2));
    }

    #[test]
    fn no_underflow_for_tiny_values() {
        // exp(-5000) underflows in linear space; log space must not.
        let got = log_sum_exp(&[-5000.0, -5000.0, -5000.0, -5000.0]);
        let exact = -5000.0 + libm::log(4.0);
        assert!((got - exact).abs() <= bound64(got, 4), "{got} vs {exact}");
        let got = log_add_exp(-5000.0, -5001.0);
        let exact = -5000.0 + libm::log1p(libm::exp(-1.0));
        assert!((got - exact).abs() <= bound64(got, 2));
    }

    #[test]
    fn sum_equals_fold_of_add() {
        let xs = [-3.25, 0.5, -100.0, 2.0, NINF, -0.125];
        let folded = xs.iter().fold(NINF, |acc, &x| log_add_exp(acc, x));
        let direct = log_sum_exp(&xs);
        assert!((folded - direct).abs() <= 2.0 * bound64(direct, xs.len()));
        let lin: f64 = xs.iter().map(|&x| libm::exp(x)).sum();
        assert!((direct - libm::log(lin)).abs() <= bound64(direct, xs.len()) + 4.0 * f64::EPSILON);
    }

    #[test]
    fn f32_matches_f64() {
        let xs32 = [-3.25f32, 0.5, -10.0, 2.0];
        let xs64: [f64; 4] = [-3.25, 0.5, -10.0, 2.0];
        let a = log_sum_exp_f32(&xs32) as f64;
        let b = log_sum_exp(&xs64);
        let eps = f32::EPSILON as f64;
        assert!((a - b).abs() <= 7.0 * eps * (1.0 + b.abs()), "{a} vs {b}");
        let a = log_add_exp_f32(-1.0, -2.0) as f64;
        let b = log_add_exp(-1.0, -2.0);
        assert!((a - b).abs() <= 3.0 * eps * (1.0 + b.abs()));
    }

    /// The stated bounds hold for f32, using the f64 functions (about 2^29 times more
    /// accurate) as the exact value, on pseudo-random inputs from a fixed seed.
    #[test]
    fn f32_error_bound_holds_on_random_inputs() {
        let mut state: u64 = 0x9E37_79B9_7F4A_7C15;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            // Uniform in [-200, 50), sometimes -inf.
            if state.is_multiple_of(17) {
                f32::NEG_INFINITY
            } else {
                (state >> 11) as f32 / (1u64 << 53) as f32 * 250.0 - 200.0
            }
        };
        let eps = f32::EPSILON as f64;
        for _ in 0..20_000 {
            let (a, b) = (next(), next());
            let got = log_add_exp_f32(a, b);
            let exact = log_add_exp(a as f64, b as f64);
            if exact == f64::NEG_INFINITY {
                assert_eq!(got, f32::NEG_INFINITY);
                continue;
            }
            let err = (got as f64 - exact).abs();
            assert!(
                err <= 3.0 * eps * (1.0 + exact.abs()),
                "{a} {b}: {got} vs {exact}"
            );
        }
        for n in 1..=16usize {
            for _ in 0..500 {
                let mut xs = [0f32; 16];
                let mut xs64 = [0f64; 16];
                for i in 0..n {
                    xs[i] = next();
                    xs64[i] = xs[i] as f64;
                }
                let got = log_sum_exp_f32(&xs[..n]);
                let exact = log_sum_exp(&xs64[..n]);
                if exact == f64::NEG_INFINITY {
                    assert_eq!(got, f32::NEG_INFINITY);
                    continue;
                }
                let err = (got as f64 - exact).abs();
                let bound = (n as f64 + 3.0) * eps * (1.0 + exact.abs());
                assert!(err <= bound, "n={n}: {got} vs {exact}, err {err} > {bound}");
            }
        }
    }
}
