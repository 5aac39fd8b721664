//! The original MERL `.binary` BRDF format (Matusik et al. 2003), which users
//! of measured data have: three little-endian i32 dimensions (theta_h,
//! theta_d, phi_d bins; 90 x 90 x 180 in the database), then the R, G and B
//! tables as f64, each `dims` values long, theta_h slowest. Stored values are
//! scaled per channel (R 1/1500, G 1.15/1500, B 1.66/1500); negative values
//! mark unmeasured cells.
//!
//! Lookup as the database's reference reader does: half/difference angles,
//! theta_h index `sqrt(theta_h / (pi/2)) N_h` (denser near the highlight),
//! theta_d `theta_d / (pi/2) N_d`, phi_d folded into [0, pi) by reciprocity,
//! `phi_d / pi N_p`, nearest cell (truncation, clamped).
//!
//! What the simulation keeps of a table is [`MerlMono`]: its channels
//! weighted for the monochrome sensor once, in f32, a sixth of the file's
//! size in memory (5.8 MB against 35 MB per material of the database), so
//! a set of a hundred tables is read in 0.6 GB rather than 3.5.
use super::Brdf;
use super::nbrdf::LUMINANCE;
use anyhow::{Context, bail, ensure};
use nalgebra::Vector3;
use std::f64::consts::{FRAC_PI_2, PI};
use std::path::Path;

/// Channel scales of the stored values.
pub const MERL_SCALE: [f64; 3] = [1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0];
/// Dimensions of the database's files.
pub const MERL_DIMS: [usize; 3] = [90, 90, 180];

/// A MERL table in memory.
#[derive(Clone, Debug, PartialEq)]
pub struct MerlTable {
    /// theta_h, theta_d, phi_d bins.
    pub dims: [usize; 3],
    /// Stored values: R table, then G, then B (unscaled, as in the file).
    pub values: Vec<f64>,
    /// Spectral weights of R, G, B for a monochrome sensor.
    pub channel_weights: [f64; 3],
}

impl MerlTable {
    /// Cells per channel.
    pub fn cells(&self) -> usize {
        self.dims.iter().product()
    }

    /// Parses the bytes of a `.binary` file; `origin` names it in errors.
    pub fn parse(bytes: &[u8], origin: &str) -> anyhow::Result<Self> {
        ensure!(bytes.len() >= 12, "{origin}: {} bytes is too short for a MERL header (12)", bytes.len());
        let mut dims = [0usize; 3];
        for (k, d) in dims.iter_mut().enumerate() {
            let x = i32::from_le_bytes(bytes[4 * k..4 * k + 4].try_into().unwrap());
            ensure!((1..=4096).contains(&x), "{origin}: dimension {k} = {x} is not 1..=4096");
            *d = x as usize;
        }
        let cells: usize = dims.iter().product();
        let want = 12 + 3 * cells * 8;
        if bytes.len() != want {
            bail!(
                "{origin}: {} bytes, but dimensions {dims:?} need {want} (12-byte header + 3 x {cells} f64)",
                bytes.len()
            );
        }
        let values: Vec<f64> = bytes[12..].chunks_exact(8).map(|c| f64::from_le_bytes(c.try_into().unwrap())).collect();
        if let Some(i) = values.iter().position(|x| !x.is_finite()) {
            bail!("{origin}: value {i} (channel {}, cell {}) is not finite", i / cells, i % cells);
        }
        // MERL marks a cell it did not measure with a negative value, and
        // the lookup reads such a cell as black: a table of nothing else
        // would pass for a black surface.
        ensure!(
            values.iter().any(|x| *x > 0.0),
            "{origin}: no cell holds a measurement (every value is zero or negative, and MERL marks a cell it did \
             not measure negative); check that the file is the material's table"
        );
        Ok(Self { dims, values, channel_weights: LUMINANCE })
    }

    /// Reads a `.binary` file.
    pub fn load(path: &Path) -> anyhow::Result<Self> {
        let bytes = std::fs::read(path).with_context(|| format!("{}: cannot read", path.display()))?;
        Self::parse(&bytes, &path.display().to_string())
    }

    /// Reads a `.binary` file as the simulation keeps it: weighted by
    /// `channel_weights` ([`Self::monochrome`]).
    pub fn load_monochrome(path: &Path, channel_weights: [f64; 3]) -> anyhow::Result<MerlMono> {
        Ok(Self { channel_weights, ..Self::load(path)? }.monochrome())
    }

    /// The file's bytes.
    pub fn to_bytes(&self) -> Vec<u8> {
        assert_eq!(self.values.len(), 3 * self.cells());
        let mut out = Vec::with_capacity(12 + 8 * self.values.len());
        for d in self.dims {
            out.extend_from_slice(&(d as i32).to_le_bytes());
        }
        for x in &self.values {
            out.extend_from_slice(&x.to_le_bytes());
        }
        out
    }

    /// Writes a `.binary` file atomically.
    pub fn save(&self, path: &Path) -> anyhow::Result<()> {
        crate::output::io::write_atomic(path, &self.to_bytes())
    }

    /// Cell index of a direction pair (None below the horizon).
    pub fn cell(&self, wi: &Vector3<f64>, wo: &Vector3<f64>) -> Option<usize> {
        cell_of(self.dims, wi, wo)
    }

    /// The table as the simulation reads it: each cell's channels scaled,
    /// unmeasured ones read as 0, weighted by [`Self::channel_weights`], in
    /// f32 (the measurements' own precision is far coarser).
    pub fn monochrome(&self) -> MerlMono {
        let values = (0..self.cells()).map(|c| self.cell_f_r(c) as f32).collect();
        MerlMono { dims: self.dims, values }
    }

    /// RGB f_r (1/sr); unmeasured cells read 0.
    pub fn rgb(&self, wi: &Vector3<f64>, wo: &Vector3<f64>) -> [f64; 3] {
        self.cell(wi, wo).map_or([0.0; 3], |c| self.cell_rgb(c))
    }

    /// Cell `c`'s RGB f_r (1/sr), scaled; an unmeasured channel reads 0.
    fn cell_rgb(&self, c: usize) -> [f64; 3] {
        let n = self.cells();
        core::array::from_fn(|k| (self.values[k * n + c] * MERL_SCALE[k]).max(0.0))
    }

    /// Cell `c`'s f_r for the monochrome sensor: its RGB weighted.
    fn cell_f_r(&self, c: usize) -> f64 {
        self.cell_rgb(c).iter().zip(&self.channel_weights).map(|(f, w)| f * w).sum()
    }
}

impl Brdf for MerlTable {
    fn f_r(&self, wi: &Vector3<f64>, wo: &Vector3<f64>) -> f64 {
        self.cell(wi, wo).map_or(0.0, |c| self.cell_f_r(c))
    }
}

/// Cell index of a direction pair in a table of `dims` (None below the horizon).
fn cell_of(dims: [usize; 3], wi: &Vector3<f64>, wo: &Vector3<f64>) -> Option<usize> {
    if wi.z <= 0.0 || wo.z <= 0.0 {
        return None;
    }
    let (theta_h, d) = super::nbrdf::half_and_difference(wi, wo);
    let theta_d = d.z.clamp(-1.0, 1.0).acos();
    let mut phi_d = d.y.atan2(d.x);
    if phi_d < 0.0 {
        phi_d += PI;
    }
    let [nh, nd, np] = dims;
    let clampi = |x: f64, n: usize| (x.max(0.0) as usize).min(n - 1);
    let ih = clampi((theta_h / FRAC_PI_2).max(0.0).sqrt() * nh as f64, nh);
    let id = clampi(theta_d / FRAC_PI_2 * nd as f64, nd);
    let ip = clampi(phi_d / PI * np as f64, np);
    Some(ip + np * (id + nd * ih))
}

/// A MERL table as the simulation reads it ([`MerlTable::monochrome`]):
/// one f_r (1/sr) per cell, for the monochrome sensor.
#[derive(Clone, Debug, PartialEq)]
pub struct MerlMono {
    dims: [usize; 3],
    values: Vec<f32>,
}

impl Brdf for MerlMono {
    fn f_r(&self, wi: &Vector3<f64>, wo: &Vector3<f64>) -> f64 {
        cell_of(self.dims, wi, wo).map_or(0.0, |c| f64::from(self.values[c]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::forward::brdf::{light_dir, view_dir};

    fn small() -> MerlTable {
        let dims = [6, 5, 8];
        let cells = 6 * 5 * 8;
        let values = (0..3 * cells)
            .map(|i| 1500.0 * (0.1 + (i % cells) as f64 / cells as f64) * (1 + i / cells) as f64)
            .collect();
        MerlTable { dims, values, channel_weights: LUMINANCE }
    }

    #[test]
    fn round_trip_through_a_file_and_lookup() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("small.binary");
        let t = small();
        t.save(&p).unwrap();
        let back = MerlTable::load(&p).unwrap();
        assert_eq!(back, t);
        // The mirror direction at normal incidence sits in theta_h bin 0.
        let c = t.cell(&light_dir(0.0), &view_dir(0.0)).unwrap();
        assert_eq!(c / (5 * 8), 0);
        // Values are scaled per channel and weighted by luminance.
        let rgb = t.rgb(&light_dir(30.0), &view_dir(30.0));
        assert!(rgb.iter().all(|x| *x > 0.0));
        let f = t.f_r(&light_dir(30.0), &view_dir(30.0));
        assert!((f - (0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2])).abs() < 1e-15);
        assert_eq!(t.f_r(&light_dir(95.0), &view_dir(30.0)), 0.0);
    }

    #[test]
    fn the_monochrome_form_reads_as_the_table_to_f32() {
        let mut t = small();
        // An unmeasured cell in one channel reads as 0 there in both forms.
        let c = t.cell(&light_dir(20.0), &view_dir(40.0)).unwrap();
        t.values[c] = -1.0;
        t.channel_weights = [0.5, 0.3, 0.2];
        let mono = t.monochrome();
        for (i, o) in [(0.0, 0.0), (20.0, 40.0), (30.0, 30.0), (60.0, 10.0), (85.0, 80.0), (95.0, 30.0)] {
            let (a, b) = (t.f_r(&light_dir(i), &view_dir(o)), mono.f_r(&light_dir(i), &view_dir(o)));
            assert!((a - b).abs() <= 1e-6 * a.abs(), "{i} {o}: {a} vs {b}");
        }
        assert_eq!(mono.values.len(), t.cells());
    }

    #[test]
    fn malformed_files_are_refused() {
        let t = small();
        let mut b = t.to_bytes();
        b.pop();
        assert!(format!("{:#}", MerlTable::parse(&b, "x.binary").unwrap_err()).contains("need"));
        let mut b = t.to_bytes();
        b[0..4].copy_from_slice(&(-1i32).to_le_bytes());
        assert!(format!("{:#}", MerlTable::parse(&b, "x.binary").unwrap_err()).contains("dimension 0"));
        let mut b = t.to_bytes();
        b[12..20].copy_from_slice(&f64::NAN.to_le_bytes());
        assert!(format!("{:#}", MerlTable::parse(&b, "x.binary").unwrap_err()).contains("not finite"));
        assert!(MerlTable::parse(&[0; 5], "x.binary").is_err());
        // Every cell unmeasured: no surface, not a black one.
        let empty = MerlTable { values: vec![-1.0; t.values.len()], ..t.clone() };
        let e = format!("{:#}", MerlTable::parse(&empty.to_bytes(), "x.binary").unwrap_err());
        assert!(e.contains("x.binary") && e.contains("no cell holds a measurement"), "{e}");
    }
}
