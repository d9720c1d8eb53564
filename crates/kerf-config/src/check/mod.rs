//! Validation with access to the source text, so that errors carry line and column: the
//! checker and its checks of single values.

mod drives;
mod ethercat;
mod ethercat_objects;
mod homing;
mod machine;
mod serve;
mod top;

use kerf_geom::PerAxis;
use std::ops::{Range, RangeInclusive};
use std::path::Path;

use toml::Spanned;

use crate::raw::*;
use crate::toml_words::{number, position_of};
use crate::*;

/// `true` for the name of an I/O bit or an `[io]` entry: 1 to 64 ASCII letters, digits,
/// `_` or `-`, starting with a letter.
pub(crate) fn valid_io_name(name: &str) -> bool {
    (1..=64).contains(&name.len())
        && name.starts_with(|c: char| c.is_ascii_alphabetic())
        && name
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-')
}

/// Validation with access to the source text, so that errors carry line and column.
pub(crate) struct Checker<'a> {
    pub(crate) text: &'a str,
    pub(crate) origin: &'a str,
    /// The directory relative file names are resolved against.
    pub(crate) dir: &'a Path,
}

impl Checker<'_> {
    pub(crate) fn error(&self, span: Range<usize>, message: String) -> ConfigError {
        ConfigError::Invalid {
            origin: self.origin.to_string(),
            position: Some(position_of(self.text, span.start)),
            message,
        }
    }

    /// A value within `range` (inclusive; NaN is never within), in `unit`.
    pub(crate) fn within(
        &self,
        key: &str,
        unit: &str,
        range: RangeInclusive<f64>,
        value: &Spanned<f64>,
    ) -> Result<f64, ConfigError> {
        let v = *value.get_ref();
        if range.contains(&v) {
            Ok(v)
        } else {
            Err(self.error(
                value.span(),
                format!(
                    "`{key}` must be between {} and {} {unit}, found {}",
                    number(*range.start()),
                    number(*range.end()),
                    number(v)
                ),
            ))
        }
    }

    /// A coordinate-like value: finite and at most [`MAX_COORDINATE_MM`] in magnitude.
    pub(crate) fn coordinate(
        &self,
        key: &str,
        unit: &str,
        value: &Spanned<f64>,
    ) -> Result<f64, ConfigError> {
        self.within(key, unit, -MAX_COORDINATE_MM..=MAX_COORDINATE_MM, value)
    }

    /// A travel range: both ends within ±[`MAX_COORDINATE_MM`] and `min < max`.
    pub(crate) fn range(
        &self,
        keys: (&str, &str),
        unit: &str,
        min: &Spanned<f64>,
        max: &Spanned<f64>,
    ) -> Result<(f64, f64), ConfigError> {
        let lo = self.coordinate(keys.0, unit, min)?;
        let hi = self.coordinate(keys.1, unit, max)?;
        if lo < hi {
            Ok((lo, hi))
        } else {
            Err(self.error(
                max.span(),
                format!(
                    "`{}` ({hi}) must be greater than `{}` ({lo})",
                    keys.1, keys.0
                ),
            ))
        }
    }

    pub(crate) fn linear(
        &self,
        name: &str,
        raw: &RawLinearAxis,
    ) -> Result<LinearAxis, ConfigError> {
        let key = |k: &str| format!("axes.{name}.{k}");
        let (min_mm, max_mm) = self.range(
            (&key("min_mm"), &key("max_mm")),
            "mm",
            &raw.min_mm,
            &raw.max_mm,
        )?;
        Ok(LinearAxis {
            velocity_mm_s: self.within(
                &key("velocity_mm_s"),
                "mm/s",
                VELOCITY_RANGE,
                &raw.velocity_mm_s,
            )?,
            acceleration_mm_s2: self.within(
                &key("acceleration_mm_s2"),
                "mm/s²",
                ACCELERATION_RANGE,
                &raw.acceleration_mm_s2,
            )?,
            jerk_mm_s3: self.within(&key("jerk_mm_s3"), "mm/s³", JERK_RANGE, &raw.jerk_mm_s3)?,
            min_mm,
            max_mm,
        })
    }

    pub(crate) fn rotary(
        &self,
        name: &str,
        raw: &Option<RawRotaryAxis>,
    ) -> Result<Option<RotaryAxis>, ConfigError> {
        let Some(raw) = raw else { return Ok(None) };
        let key = |k: &str| format!("axes.{name}.{k}");
        let (min_deg, max_deg) = self.range(
            (&key("min_deg"), &key("max_deg")),
            "deg",
            &raw.min_deg,
            &raw.max_deg,
        )?;
        Ok(Some(RotaryAxis {
            velocity_deg_s: self.within(
                &key("velocity_deg_s"),
                "deg/s",
                VELOCITY_RANGE,
                &raw.velocity_deg_s,
            )?,
            acceleration_deg_s2: self.within(
                &key("acceleration_deg_s2"),
                "deg/s²",
                ACCELERATION_RANGE,
                &raw.acceleration_deg_s2,
            )?,
            jerk_deg_s3: self.within(
                &key("jerk_deg_s3"),
                "deg/s³",
                JERK_RANGE,
                &raw.jerk_deg_s3,
            )?,
            min_deg,
            max_deg,
        }))
    }

    pub(crate) fn offset(
        &self,
        key: &str,
        raw: &Option<Spanned<Vec<f64>>>,
    ) -> Result<[f64; 3], ConfigError> {
        let Some(raw) = raw else {
            return Ok([0.0; 3]);
        };
        match raw.get_ref().as_slice() {
            &[x, y, z] if [x, y, z].iter().all(|v| v.abs() <= MAX_COORDINATE_MM) => Ok([x, y, z]),
            _ => Err(self.error(
                raw.span(),
                format!(
                    "`work_offsets.{key}` must be three numbers [x, y, z] between {} and {} mm",
                    number(-MAX_COORDINATE_MM),
                    number(MAX_COORDINATE_MM)
                ),
            )),
        }
    }

    /// A whole number within `range`.
    pub(crate) fn integer(
        &self,
        key: &str,
        what: &str,
        range: RangeInclusive<u32>,
        value: &Spanned<i64>,
    ) -> Result<u32, ConfigError> {
        match u32::try_from(*value.get_ref()) {
            Ok(v) if range.contains(&v) => Ok(v),
            _ => Err(self.error(
                value.span(),
                format!(
                    "`{key}` must be {what} from {} to {}, found {}",
                    range.start(),
                    range.end(),
                    value.get_ref()
                ),
            )),
        }
    }

    /// An optional number within `range`, or `default`.
    pub(crate) fn within_or(
        &self,
        key: &str,
        unit: &str,
        range: RangeInclusive<f64>,
        value: &Option<Spanned<f64>>,
        default: f64,
    ) -> Result<f64, ConfigError> {
        match value {
            None => Ok(default),
            Some(v) => self.within(key, unit, range, v),
        }
    }

    /// An optional whole number within `range`, or `default`.
    pub(crate) fn integer_or(
        &self,
        key: &str,
        what: &str,
        range: RangeInclusive<u32>,
        value: &Option<Spanned<i64>>,
        default: u32,
    ) -> Result<u32, ConfigError> {
        match value {
            None => Ok(default),
            Some(v) => self.integer(key, what, range, v),
        }
    }

    /// A stored position: `[x, y, z]` (mm) or `[x, y, z, a, b, c]` (mm, degrees).
    pub(crate) fn home(
        &self,
        key: &str,
        raw: &Option<Spanned<Vec<f64>>>,
    ) -> Result<PerAxis<f64>, ConfigError> {
        let Some(raw) = raw else {
            return Ok([0.0; 6]);
        };
        let v = raw.get_ref();
        if matches!(v.len(), 3 | 6) && v.iter().all(|x| x.abs() <= MAX_COORDINATE_MM) {
            let mut out = [0.0; 6];
            out[..v.len()].copy_from_slice(v);
            return Ok(out);
        }
        Err(self.error(
            raw.span(),
            format!(
                "`{key}` must be [x, y, z] or [x, y, z, a, b, c] (mm, degrees) between {} and {}",
                number(-MAX_COORDINATE_MM),
                number(MAX_COORDINATE_MM)
            ),
        ))
    }
}
