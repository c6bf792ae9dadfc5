//! Where the sun is: fixed in the sky, or worked out for a date-time and a
//! place by NREL's Solar Position Algorithm (the `solar-positioning`
//! crate). Lighting follows it; a shadow study asks "21 June, 15:00 local
//! time".

use chrono::{DateTime, FixedOffset};
pub use relief_renderer::SunAngles;
use solar_positioning::{Location, SolarPositions, delta_t};

/// The sun of a scene or of a request.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Sun {
    /// Fixed azimuth (degrees clockwise from north) and elevation (degrees
    /// above the horizon) at every place.
    Fixed { azimuth_deg: f64, elevation_deg: f64 },
    /// The sun at this instant, over the place it lights.
    At(DateTime<FixedOffset>),
}

impl Default for Sun {
    /// From the north-west, 45 degrees up: the cartographer's light.
    fn default() -> Self {
        let SunAngles { azimuth_deg, elevation_deg } = SunAngles::DEFAULT;
        Self::Fixed { azimuth_deg, elevation_deg }
    }
}

impl Sun {
    /// A sun from a date-time (RFC 3339 with its UTC offset, as
    /// `2026-06-21T15:00:00+02:00`) or from an azimuth and an elevation,
    /// not both. Errors name the field.
    pub fn parse(
        time: Option<&str>,
        azimuth_deg: Option<f64>,
        elevation_deg: Option<f64>,
    ) -> Result<Self, (&'static str, String)> {
        match (time, azimuth_deg, elevation_deg) {
            (Some(_), Some(_), _) | (Some(_), _, Some(_)) => {
                Err(("time", "give a time or an azimuth and an elevation, not both".into()))
            }
            (Some(t), None, None) => Self::parse_time(t).map(Self::At).map_err(|m| ("time", m)),
            (None, Some(azimuth_deg), Some(elevation_deg)) => {
                if !azimuth_deg.is_finite() {
                    return Err(("azimuth_deg", format!("{azimuth_deg} is not a number of degrees")));
                }
                if !(elevation_deg.is_finite() && (-90.0..=90.0).contains(&elevation_deg)) {
                    return Err(("elevation_deg", format!("{elevation_deg} is not from -90 to 90 degrees")));
                }
                Ok(Self::Fixed { azimuth_deg: azimuth_deg.rem_euclid(360.0), elevation_deg })
            }
            (None, Some(_), None) => Err(("elevation_deg", "give it with azimuth_deg".into())),
            (None, None, Some(_)) => Err(("azimuth_deg", "give it with elevation_deg".into())),
            (None, None, None) => Ok(Self::default()),
        }
    }

    fn parse_time(text: &str) -> Result<DateTime<FixedOffset>, String> {
        DateTime::parse_from_rfc3339(text.trim()).map_err(|e| {
            format!(
                "'{text}' is not a date-time with its UTC offset, as 2026-06-21T15:00:00+02:00 or \
                 2026-06-21T13:00:00Z ({e})"
            )
        })
    }

    /// The sun over `lon_deg`, `lat_deg` (at sea level, without refraction:
    /// the geometric sun). Errors for a time outside SPA's years
    /// (-2000 to 6000).
    pub fn angles(&self, lon_deg: f64, lat_deg: f64) -> Result<SunAngles, String> {
        match *self {
            Self::Fixed { azimuth_deg, elevation_deg } => Ok(SunAngles { azimuth_deg, elevation_deg }),
            Self::At(time) => {
                let dt = delta_t::estimate_from_date_like(&time).map_err(|e| format!("sun time {time}: {e}"))?;
                sun_at(&time, lon_deg, lat_deg, dt)
            }
        }
    }

    /// What the scene state and answers say: the time, or "fixed".
    pub fn describe(&self) -> String {
        match self {
            Self::Fixed { azimuth_deg, elevation_deg } => {
                format!("fixed: azimuth {azimuth_deg} deg, elevation {elevation_deg} deg")
            }
            Self::At(time) => format!("at {}", time.to_rfc3339()),
        }
    }
}

/// SPA's sun at `time` over a place, with delta T (TT - UT1) given in
/// seconds. Latitudes are clamped just inside the poles, where azimuth
/// has no meaning and SPA refuses exactly +-90.
pub fn sun_at(time: &DateTime<FixedOffset>, lon_deg: f64, lat_deg: f64, delta_t_s: f64) -> Result<SunAngles, String> {
    let location = Location { latitude: lat_deg.clamp(-89.999_999, 89.999_999), longitude: wrap_lon(lon_deg) };
    let position = SolarPositions::new()
        .at(time, location, 0.0, delta_t_s, None)
        .map_err(|e| format!("sun at {time} over {lon_deg}, {lat_deg}: {e}"))?;
    Ok(SunAngles { azimuth_deg: position.azimuth(), elevation_deg: position.elevation_angle() })
}

/// A longitude in -180..180 (a camera may be past the antimeridian).
fn wrap_lon(lon: f64) -> f64 {
    let l = (lon + 180.0).rem_euclid(360.0) - 180.0;
    if l.is_finite() { l } else { 0.0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_time_needs_its_offset_and_excludes_fixed_angles() {
        assert!(matches!(Sun::parse(Some("2026-06-21T15:00:00+02:00"), None, None), Ok(Sun::At(_))));
        let (field, message) = Sun::parse(Some("2026-06-21T15:00:00"), None, None).unwrap_err();
        assert_eq!(field, "time");
        assert!(message.contains("UTC offset"), "{message}");
        assert_eq!(Sun::parse(Some("2026-06-21T15:00:00Z"), Some(10.0), None).unwrap_err().0, "time");
        assert_eq!(Sun::parse(None, Some(10.0), None).unwrap_err().0, "elevation_deg");
        assert_eq!(Sun::parse(None, Some(10.0), Some(91.0)).unwrap_err().0, "elevation_deg");
        assert_eq!(
            Sun::parse(None, Some(-45.0), Some(10.0)).unwrap(),
            Sun::Fixed { azimuth_deg: 315.0, elevation_deg: 10.0 }
        );
        assert_eq!(Sun::parse(None, None, None).unwrap(), Sun::default());
    }

    #[test]
    fn the_sun_is_south_at_noon_and_down_at_midnight() {
        // Greenwich, the June solstice: near 62 degrees up at noon UT, due
        // south; below the horizon at midnight.
        let noon = Sun::parse(Some("2026-06-21T12:00:00Z"), None, None).unwrap().angles(0.0, 51.48).unwrap();
        assert!((noon.elevation_deg - 61.9).abs() < 0.3, "{noon:?}");
        assert!((noon.azimuth_deg - 180.0).abs() < 2.0, "{noon:?}");
        let night = Sun::parse(Some("2026-06-21T00:00:00Z"), None, None).unwrap().angles(0.0, 51.48).unwrap();
        assert!(night.elevation_deg < -10.0, "{night:?}");
        // The same instant written in another offset is the same sun.
        let paris = Sun::parse(Some("2026-06-21T14:00:00+02:00"), None, None).unwrap().angles(0.0, 51.48).unwrap();
        assert_eq!(paris, noon);
        // Past the antimeridian and at the pole: numbers, not errors.
        assert!(Sun::parse(Some("2026-06-21T12:00:00Z"), None, None).unwrap().angles(190.0, 90.0).is_ok());
    }
}
