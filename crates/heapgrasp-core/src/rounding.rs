//! `floor` and `ceil` without libm calls.
//!
//! The baseline x86-64 target has no `roundsd`, so `f64::floor` is a function call
//! there; in per-cell loops that call dominates. These are exact for |x| < 2^53 (every
//! f64 of larger magnitude is an integer already); beyond ±2^63 they saturate, which
//! callers make harmless by clamping the result to their index range.

/// `floor(x)`; see the module docs.
#[inline(always)]
pub(crate) fn floor_fast(x: f64) -> f64 {
    let t = x as i64 as f64;
    if t > x {
        t - 1.0
    } else {
        t
    }
}

/// `ceil(x)`; see the module docs.
#[inline(always)]
pub(crate) fn ceil_fast(x: f64) -> f64 {
    let t = x as i64 as f64;
    if t < x {
        t + 1.0
    } else {
        t
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equal_to_floor_and_ceil() {
        let xs = [
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            2.999_999_999,
            -2.999_999_999,
            1e15 + 0.5,
            -1e15 - 0.5,
            4.5e15,
            -4.5e15,
            1e-300,
            -1e-300,
        ];
        for x in xs {
            assert_eq!(floor_fast(x), x.floor(), "floor {x}");
            assert_eq!(ceil_fast(x), x.ceil(), "ceil {x}");
        }
    }
}
