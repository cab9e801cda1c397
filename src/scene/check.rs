//! The checks every scene key goes through: a number's range, a per-ball
//! array's length, an error naming origin, line, key, value and what is
//! allowed (used by `validate` and `granular`).

use std::fmt::Display;

use super::*;

pub(super) const POS: &str = "must be a finite number > 0";

pub(super) struct Check<'a> {
    pub(super) spec: &'a SceneSpec,
}

impl Check<'_> {
    pub(super) fn err(
        &self,
        key: &str,
        value: impl Display,
        allowed: impl Into<String>,
    ) -> InputError {
        InputError::Invalid {
            origin: self.spec.origin.clone(),
            line: self.spec.line_of(key),
            key: key.to_string(),
            value: value.to_string(),
            allowed: allowed.into(),
        }
    }

    pub(super) fn num(
        &self,
        key: &str,
        x: f64,
        ok: fn(f64) -> bool,
        allowed: &str,
    ) -> Result<f64, InputError> {
        if x.is_finite() && ok(x) {
            Ok(x)
        } else {
            Err(self.err(key, x, allowed))
        }
    }

    pub(super) fn opt(
        &self,
        key: &str,
        x: Option<f64>,
        ok: fn(f64) -> bool,
        allowed: &str,
    ) -> Result<Option<f64>, InputError> {
        x.map(|x| self.num(key, x, ok, allowed)).transpose()
    }

    /// A per-ball (or per-contact) array of `n` values, each passing `ok`.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn per(
        &self,
        key: &str,
        v: Option<&PerBall>,
        default: f64,
        n: usize,
        what: &str,
        ok: fn(f64) -> bool,
        allowed: &str,
    ) -> Result<Vec<f64>, InputError> {
        let values = match v {
            None => vec![default; n],
            Some(PerBall::Scalar(x)) => vec![*x; n],
            Some(PerBall::List(l)) if l.len() == n => l.clone(),
            Some(p @ PerBall::List(l)) => {
                return Err(self.err(
                    key,
                    p,
                    format!(
                        "an array of {n} values (one per {what}) or one number; got {}",
                        l.len()
                    ),
                ))
            }
        };
        // The key is only spelt out for an error (this runs for every scene).
        for (i, &x) in values.iter().enumerate() {
            if x.is_finite() && ok(x) {
                continue;
            }
            let k = if matches!(v, Some(PerBall::List(_))) {
                format!("{key}[{i}]")
            } else {
                key.to_string()
            };
            self.num(&k, x, ok, allowed)?;
        }
        Ok(values)
    }
}

pub(super) fn positive(x: f64) -> bool {
    x > 0.0
}
pub(super) fn poisson(x: f64) -> bool {
    (0.0..0.5).contains(&x)
}
pub(super) const POISSON: &str = "must be in [0, 0.5)";
pub(super) fn non_negative(x: f64) -> bool {
    x >= 0.0
}
pub(super) fn finite_non_negative(x: f64) -> bool {
    (0.0..f64::INFINITY).contains(&x)
}
pub(super) fn any(_: f64) -> bool {
    true
}
