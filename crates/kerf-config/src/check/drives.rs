//! The drive side checked: every axis's drive and `[safety]`.

use kerf_drive::MAX_AXES;
use kerf_drive::cia402::Scale;
use toml::Spanned;

use crate::raw::*;
use crate::toml_words::{number, position_of};
use crate::*;

use super::Checker;

impl Checker<'_> {
    /// The drive side of axis `name`: `[axes.NAME.drive]` and the following-error keys
    /// (`ferror`, `min_ferror`, spanned), in `unit` (`mm` or `deg`); `travel` is the axis's
    /// travel range, which must fit in the drive's 32-bit counts.
    pub(crate) fn axis_drive(
        &self,
        name: &str,
        unit: &str,
        raw: &Option<RawDrive>,
        ferror: (&Option<Spanned<f64>>, &Option<Spanned<f64>>),
        travel: (f64, f64),
    ) -> Result<AxisDrive, ConfigError> {
        let empty = RawDrive::default();
        let raw = raw.as_ref().unwrap_or(&empty);
        let key = |k: &str| format!("axes.{name}.drive.{k}");
        let kind = match &raw.kind {
            None => DriveKind::Sim,
            Some(k) if k.get_ref() == "sim" => DriveKind::Sim,
            // Checked against `[ethercat]`, and set, by `Checker::ethercat`.
            Some(k) if k.get_ref() == "ethercat" => DriveKind::Sim,
            Some(k) => {
                return Err(self.error(
                    k.span(),
                    format!(
                        "`{}` must be \"sim\" or \"ethercat\", found `{}`",
                        key("kind"),
                        k.get_ref()
                    ),
                ));
            }
        };
        // The scale key carries the axis's unit; the other one is a mistake worth naming.
        let (scale_key, wrong) = if unit == "mm" {
            ("counts_per_mm", &raw.counts_per_deg)
        } else {
            ("counts_per_deg", &raw.counts_per_mm)
        };
        if let Some(w) = wrong {
            return Err(self.error(
                w.span(),
                format!(
                    "axis {name} is measured in {unit}: its scale is `{}`",
                    key(scale_key)
                ),
            ));
        }
        let scale_raw = if unit == "mm" {
            &raw.counts_per_mm
        } else {
            &raw.counts_per_deg
        };
        let counts_per_unit = self.within_or(
            &key(scale_key),
            &format!("counts/{unit}"),
            COUNTS_PER_UNIT_RANGE,
            scale_raw,
            DEFAULT_COUNTS_PER_UNIT,
        )?;
        let reach = travel.0.abs().max(travel.1.abs()) * counts_per_unit;
        if reach > f64::from(i32::MAX) {
            let message = format!(
                "`{}` = {} puts the travel limit {} {unit} at {} counts, beyond the drive's 32-bit position ({})",
                key(scale_key),
                number(counts_per_unit),
                number(travel.0.abs().max(travel.1.abs())),
                number(reach),
                i32::MAX
            );
            return Err(match scale_raw {
                Some(v) => self.error(v.span(), message),
                None => ConfigError::Invalid {
                    origin: self.origin.to_string(),
                    position: None,
                    message,
                },
            });
        }
        let direction = match &raw.direction {
            None => 1,
            Some(d) if matches!(*d.get_ref(), 1 | -1) => *d.get_ref() as i32,
            Some(d) => {
                return Err(self.error(
                    d.span(),
                    format!(
                        "`{}` must be +1 or -1, found {}",
                        key("direction"),
                        d.get_ref()
                    ),
                ));
            }
        };
        let scale = Scale::new(counts_per_unit, direction).map_err(|e| ConfigError::Invalid {
            origin: self.origin.to_string(),
            position: scale_raw
                .as_ref()
                .map(|v| position_of(self.text, v.span().start)),
            message: format!("`{}`: {e}", key(scale_key)),
        })?;
        let mut d = AxisDrive::with_scale(scale);
        d.kind = kind;
        self.sim_tuning(&key, raw, &mut d.sim)?;
        d.enable_timeout_ms = self.integer_or(
            &key("enable_timeout_ms"),
            "a time in ms",
            ENABLE_TIMEOUT_RANGE_MS,
            &raw.enable_timeout_ms,
            d.enable_timeout_ms,
        )?;
        self.following_error(name, unit, ferror, &mut d)?;
        Ok(d)
    }

    /// The drive side: every axis's drive and `[safety]`.
    pub(crate) fn drive_side(
        &self,
        raw: &RawConfig,
        axes: &Axes,
    ) -> Result<DriveSide, ConfigError> {
        let mut out = [None; MAX_AXES];
        let linear = [
            ("x", &raw.axes.x, axes.x),
            ("y", &raw.axes.y, axes.y),
            ("z", &raw.axes.z, axes.z),
        ];
        for (i, (name, r, a)) in linear.into_iter().enumerate() {
            out[i] = Some(self.axis_drive(
                name,
                "mm",
                &r.drive,
                (&r.ferror_mm, &r.min_ferror_mm),
                (a.min_mm, a.max_mm),
            )?);
        }
        let rotary = [
            ("a", &raw.axes.a, axes.a),
            ("b", &raw.axes.b, axes.b),
            ("c", &raw.axes.c, axes.c),
        ];
        for (i, (name, r, a)) in rotary.into_iter().enumerate() {
            if let (Some(r), Some(a)) = (r, a) {
                out[3 + i] = Some(self.axis_drive(
                    name,
                    "deg",
                    &r.drive,
                    (&r.ferror_deg, &r.min_ferror_deg),
                    (a.min_deg, a.max_deg),
                )?);
            }
        }
        let s = &raw.safety;
        Ok(DriveSide {
            axes: out,
            margin: self.within_or(
                "safety.margin",
                "(fraction of the limits)",
                MARGIN_RANGE,
                &s.margin,
                kerf_drive::safety::DEFAULT_MARGIN,
            )?,
            stall_cycles: self.integer_or(
                "safety.stall_cycles",
                "a number of cycles",
                STALL_CYCLES_RANGE,
                &s.stall_cycles,
                kerf_drive::safety::DEFAULT_STALL_CYCLES,
            )?,
            recorder_seconds: self.within_or(
                "safety.recorder_seconds",
                "s",
                RECORDER_SECONDS_RANGE,
                &s.recorder_seconds,
                kerf_drive::recorder::DEFAULT_SECONDS,
            )?,
        })
    }

    /// The simulated drive's tuning keys of `[axes.*.drive]`, over the defaults in `sim`.
    fn sim_tuning(
        &self,
        key: &dyn Fn(&str) -> String,
        raw: &RawDrive,
        sim: &mut kerf_drive::sim::SimConfig,
    ) -> Result<(), ConfigError> {
        sim.bandwidth_hz = self.within_or(
            &key("bandwidth_hz"),
            "Hz",
            BANDWIDTH_RANGE_HZ,
            &raw.bandwidth_hz,
            sim.bandwidth_hz,
        )?;
        sim.damping = self.within_or(
            &key("damping"),
            "(damping ratio)",
            DAMPING_RANGE,
            &raw.damping,
            sim.damping,
        )?;
        sim.inertia_ratio = self.within_or(
            &key("inertia_ratio"),
            "(load inertia over the tuned inertia)",
            INERTIA_RATIO_RANGE,
            &raw.inertia_ratio,
            sim.inertia_ratio,
        )?;
        sim.velocity_feed_forward = self.within_or(
            &key("velocity_feed_forward"),
            "(gain)",
            VELOCITY_FEED_FORWARD_RANGE,
            &raw.velocity_feed_forward,
            sim.velocity_feed_forward,
        )?;
        sim.substeps = self.integer_or(
            &key("substeps"),
            "a number of steps per period",
            SUBSTEPS_RANGE,
            &raw.substeps,
            sim.substeps,
        )?;
        sim.overcurrent_accel_counts_s2 = self.within_or(
            &key("overcurrent_accel_counts_s2"),
            "counts/s²",
            DRIVE_ACCELERATION_RANGE_COUNTS_S2,
            &raw.overcurrent_accel_counts_s2,
            sim.overcurrent_accel_counts_s2,
        )?;
        sim.quick_stop_decel_counts_s2 = self.within_or(
            &key("quick_stop_decel_counts_s2"),
            "counts/s²",
            DRIVE_ACCELERATION_RANGE_COUNTS_S2,
            &raw.quick_stop_decel_counts_s2,
            sim.quick_stop_decel_counts_s2,
        )?;
        sim.following_error_window_counts = self.integer_or(
            &key("following_error_window_counts"),
            "a number of counts",
            FOLLOWING_ERROR_WINDOW_RANGE_COUNTS,
            &raw.following_error_window_counts,
            sim.following_error_window_counts,
        )?;
        Ok(())
    }

    /// The following-error limits of axis `name` (`ferror_*`, `min_ferror_*`), the smaller
    /// at most the larger.
    fn following_error(
        &self,
        name: &str,
        unit: &str,
        ferror: (&Option<Spanned<f64>>, &Option<Spanned<f64>>),
        d: &mut AxisDrive,
    ) -> Result<(), ConfigError> {
        let ferror_key = format!("axes.{name}.ferror_{unit}");
        let min_ferror_key = format!("axes.{name}.min_ferror_{unit}");
        d.ferror_mm_deg = self.within_or(
            &ferror_key,
            unit,
            FERROR_RANGE_MM,
            ferror.0,
            DEFAULT_FERROR_MM,
        )?;
        d.min_ferror_mm_deg = self.within_or(
            &min_ferror_key,
            unit,
            FERROR_RANGE_MM,
            ferror.1,
            DEFAULT_MIN_FERROR_MM,
        )?;
        if d.min_ferror_mm_deg > d.ferror_mm_deg {
            let message = format!(
                "`{min_ferror_key}` ({}) must be at most `{ferror_key}` ({})",
                number(d.min_ferror_mm_deg),
                number(d.ferror_mm_deg)
            );
            let span = ferror.1.as_ref().or(ferror.0.as_ref()).map(|v| v.span());
            return Err(match span {
                Some(span) => self.error(span, message),
                None => ConfigError::Invalid {
                    origin: self.origin.to_string(),
                    position: None,
                    message,
                },
            });
        }
        Ok(())
    }
}
