//! The checks every parameter table makes of its own values, and the error
//! that names the offending key. A leaf: each layer's `*Params` validates
//! itself with these, and the configuration file (`sweepline::config`) only
//! aggregates the tables, so no algorithm depends on the daemon's config.

/// A value out of its allowed range, named by its dotted key.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("config key `{key}`: {message}")]
pub struct ParamError {
    /// Dotted key, e.g. `icp.gate_min`.
    pub key: String,
    /// What is wrong and what is allowed.
    pub message: String,
}

/// The error for `key` with `message`.
pub fn invalid(key: &str, message: &str) -> ParamError {
    ParamError {
        key: key.to_string(),
        message: message.to_string(),
    }
}

/// `v` must be a finite number > 0.
pub fn positive(key: &str, v: f64) -> Result<(), ParamError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(invalid(
            key,
            &format!("must be a finite number > 0, got {v:?}"),
        ))
    }
}

/// `v` must be a finite number ≥ 0.
pub fn non_negative(key: &str, v: f64) -> Result<(), ParamError> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(invalid(
            key,
            &format!("must be a finite number >= 0, got {v:?}"),
        ))
    }
}

/// `v` must be a finite number.
pub fn finite(key: &str, v: f64) -> Result<(), ParamError> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(invalid(key, &format!("must be a finite number, got {v:?}")))
    }
}

/// Checks fields of a parameter table by kind, the dotted key made from the
/// table's name and the field's own name, so a key in an error can never be
/// misspelled:
///
/// ```
/// # use sweepline_core::check_keys;
/// # use sweepline_core::param_check::ParamError;
/// struct P { gate: f64, bias: f64 }
/// fn validate(p: &P) -> Result<(), ParamError> {
///     check_keys!(p, "icp", positive: [gate], finite: [bias]);
///     Ok(())
/// }
/// let e = validate(&P { gate: 0.0, bias: 1.0 }).unwrap_err();
/// assert_eq!(e.key, "icp.gate");
/// ```
#[macro_export]
macro_rules! check_keys {
    ($p:expr, $table:literal $(, $kind:ident: [$($field:ident),* $(,)?])* $(,)?) => {
        $($(
            $crate::param_check::$kind(
                concat!($table, ".", stringify!($field)),
                $p.$field,
            )?;
        )*)*
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    struct P {
        a: f64,
        b: f64,
        c: f64,
    }

    fn check(p: &P) -> Result<(), ParamError> {
        check_keys!(p, "t", positive: [a], non_negative: [b], finite: [c]);
        Ok(())
    }

    #[test]
    fn each_kind_names_its_key() {
        assert_eq!(
            check(&P {
                a: 1.0,
                b: 0.0,
                c: -3.0
            }),
            Ok(())
        );
        let key = |p: P| check(&p).unwrap_err().key;
        assert_eq!(
            key(P {
                a: 0.0,
                b: 0.0,
                c: 0.0
            }),
            "t.a"
        );
        assert_eq!(
            key(P {
                a: 1.0,
                b: -0.1,
                c: 0.0
            }),
            "t.b"
        );
        assert_eq!(
            key(P {
                a: 1.0,
                b: 0.0,
                c: f64::NAN
            }),
            "t.c"
        );
        assert_eq!(
            key(P {
                a: f64::INFINITY,
                b: 0.0,
                c: 0.0
            }),
            "t.a"
        );
    }
}
