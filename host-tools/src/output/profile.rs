//! A measured BRDF profile as the standard export formats take it (BiRD
//! universal BRDF JSON, ASTM E1392 tables): plain numbers, no device types, so
//! any layer can export. Geometry is the meter's: light in the plane of
//! incidence at `theta_i` on the -x side (azimuth 180 deg), viewer at the
//! fixed `view_deg` on the +x side (azimuth 0 deg).
use std::time::{SystemTime, UNIX_EPOCH};

/// Azimuth of the light (deg): the -x side of the plane of incidence.
pub const PHI_LIGHT_DEG: f64 = 180.0;
/// Azimuth of the viewer (deg): the +x side.
pub const PHI_VIEW_DEG: f64 = 0.0;

/// One point's profile.
#[derive(Clone, Debug, PartialEq)]
pub struct Profile {
    /// Line of the measurement.
    pub line: u32,
    /// Point (pixel) on the line.
    pub point: u16,
    /// Flag names (empty when the point is clean).
    pub flags: Vec<String>,
    /// Incidence of each bin (deg).
    pub theta_i_deg: Vec<f64>,
    /// Reflectance factor R = pi f_r per bin.
    pub reflectance: Vec<f64>,
    /// Standard uncertainty of R per bin.
    pub uncertainty: Vec<f64>,
    /// The point's gloss readings that it has: (name, value, standard
    /// uncertainty), names as `brdf_meter::gloss::NAMES`.
    pub readings: Vec<(String, f64, f64)>,
}

/// What the files say about where the profiles came from.
#[derive(Clone, Debug, PartialEq)]
pub struct ExportInfo {
    /// The viewer's zenith angle (deg).
    pub view_deg: f64,
    /// The command that made the data, e.g. `host-tools measure`.
    pub source: String,
    /// The instrument (device identity, or an offline estimate).
    pub instrument: String,
    /// The calibration (estimator kind, blob CRC).
    pub calibration: String,
    /// When (ISO 8601, UTC).
    pub timestamp: String,
    /// Solid angle one detector element sees (sr), when the user knows it:
    /// the BiRD schema requires it and the meter's description does not hold it.
    pub solid_angle_sr: Option<f64>,
}

/// Now as ISO 8601 UTC (`YYYY-MM-DDThh:mm:ss+00:00`).
pub fn utc_now() -> String {
    let secs = SystemTime::now().duration_since(UNIX_EPOCH).map_or(0, |d| d.as_secs());
    utc_of(secs)
}

/// Seconds since the epoch as ISO 8601 UTC (days to civil date: Howard
/// Hinnant's algorithm, exact for the proleptic Gregorian calendar).
pub fn utc_of(secs: u64) -> String {
    let days = (secs / 86_400) as i64;
    let rem = secs % 86_400;
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!("{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}+00:00", rem / 3600, rem % 3600 / 60, rem % 60)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn epoch_seconds_become_calendar_dates() {
        assert_eq!(utc_of(0), "1970-01-01T00:00:00+00:00");
        assert_eq!(utc_of(951_782_400), "2000-02-29T00:00:00+00:00");
        assert_eq!(utc_of(1_795_298_130), "2026-11-21T21:55:30+00:00");
    }
}
