//! `f64` helpers that `core` lacks without `std` (no libm here).

/// `x` rounded to the nearest integer, halves away from zero: what
/// `f64::round` gives, for |x| < 2^53 (the values a codec scales: steps,
/// millimetres per second); NaN gives 0, beyond the `i64` range saturates.
pub(crate) fn round(x: f64) -> f64 {
    // The cast truncates toward zero; the remainder is exact below 2^53.
    #[allow(clippy::cast_possible_truncation)]
    let t = x as i64 as f64;
    let rest = x - t;
    if rest >= 0.5 {
        t + 1.0
    } else if rest <= -0.5 {
        t - 1.0
    } else {
        t
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rounds_as_std_does() {
        let xs = [
            0.0,
            -0.0,
            0.49999999999999994,
            0.5,
            1.5,
            2.5,
            -0.5,
            -1.5,
            -2.4999,
            1e15 + 0.5,
            -1e15 - 0.5,
            123.456,
            -654.321,
            4503599627370495.5,
        ];
        for x in xs {
            assert_eq!(round(x), x.round(), "{x}");
        }
        for k in -20000..20000 {
            let x = f64::from(k) * 0.0137;
            assert_eq!(round(x), x.round(), "{x}");
        }
    }
}
