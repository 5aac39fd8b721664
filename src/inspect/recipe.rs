//! The inspection recipe: what `host-tools inspect teach` learned from a
//! reference ("golden") sample and the tolerances the device decides with.
//! One binary layout, written by the host ([`write()`], std) and read in place
//! on the device ([`RecipeView`]); signed like a calibration (the recipe's
//! bytes, then [`crate::signed`]'s 80-byte trailer) and stored A/B by
//! [`crate::store`].
//!
//! # Layout (format version 2), little-endian
//! Format 2 differs from format 1 only in what the decision does with it:
//! a format 2 recipe was taught for hysteresis along the line (a defect's
//! pixels out at least at the leaving thresholds, one of them at the
//! entering ones), a format 1 recipe for every pixel of a defect out at the
//! entering thresholds. The device reads both and decides each by the rule
//! its thresholds were set for
//! ([`RecipeSettings::along_line_hysteresis`]), so a firmware update does
//! not change what an installed recipe calls.
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 4 | magic `b"BRDI"` |
//! | 4 | 2 | format version (2; 1 is read too) |
//! | 6 | 2 | header length ([`HEADER_LEN`]) |
//! | 8 | 4 | total length (CRC included, signature trailer not) |
//! | 12 | 4 | CRC of the calibration blob it was taught with |
//! | 16 | 2 | pixels P |
//! | 18 | 2 | readings per point m |
//! | 20 | 2 | groups G (pixels sharing a noise correlation and reading gradient) |
//! | 22 | 2 | reserved, 0 |
//! | 24 | 4 | recipe version (the user's number, shown by `info`) |
//! | 28 | 4 | distance threshold to enter, `d^2`, f32 |
//! | 32 | 4 | distance threshold to leave (hysteresis), f32, <= the one to enter |
//! | 36 | 2 | minimum defect size in pixels |
//! | 38 | 2 | minimum defect size in lines |
//! | 40 | 4 | drift EWMA weight lambda, f32 in (0, 1] |
//! | 44 | 4 | drift alarm limit on the EWMA, GU, f32 |
//! | 48 | 4 | reject pulse length, us |
//! | 52 | 4 | reject delay, in the unit below |
//! | 56 | 1 | reject delay unit: 0 = us, 1 = lines (encoder counts) |
//! | 57 | 3 | reserved, 0 |
//! | 60 | 4 | window hysteresis: a window violation clears below this share of the window, f32 in (0, 1] |
//! | 64 | 24 | windows: per reading (gloss GU, haze HU, distinctness %) the lowest and highest change from the reference allowed, f32 (lowest <= 0 <= highest; +-inf = none) |
//! | 88 | 4 | teach quality (informative), f32 |
//! | 92 | 4 | lines taught |
//! | 96 | 2 G, padded to 4 | first pixel of each group, ascending, the first 0 |
//! | .. | 4 G ((m-1)m/2 + R m) | per group: the whitening of the first m - 1 normalised readings' correlation (lower triangle of `L^-1`, packed row by row), then the readings' gradient `J` (R x m, row-major: d reading / d normalised reading) |
//! | .. | 4 P (2 m + 1) | per pixel: the reference mean of the normalised readings (m), the inverse standard deviations of the first m - 1, the inverse of the m means' sum, the pixel's weight in the drift mean |
//! | end-4 | 4 | CRC-32 of everything before |
//!
//! R = [`crate::shape::READINGS`]. Everything the device computes from a
//! recipe is in [`super::decide`].
use crate::blob::CRC32;
use crate::shape::READINGS;
use serde::{Deserialize, Serialize};

/// First bytes of a recipe.
pub const MAGIC: [u8; 4] = *b"BRDI";
/// Recipe format version (the one written).
pub const FORMAT_VERSION: u16 = 2;
/// The format before hysteresis along the line, still read.
pub const FORMAT_VERSION_ENTERING_RUNS: u16 = 1;
/// Header length.
pub const HEADER_LEN: usize = 96;
/// Most groups a recipe may have.
pub const MAX_GROUPS: usize = 256;

/// Why a recipe was refused (what travels to the host).
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RecipeFault {
    /// Shorter than its header or its declared length.
    TooShort,
    /// Not a recipe.
    BadMagic,
    /// A format this firmware does not read.
    UnsupportedVersion,
    /// The declared length differs from the bytes.
    LengthMismatch,
    /// The recipe's own CRC does not match.
    CrcMismatch,
    /// Pixels or readings per point are not this device's.
    WrongShape,
    /// The group table is not ascending from pixel 0, or too many groups.
    BadGroups,
    /// A threshold, window, weight or timing is NaN or out of its range.
    BadValue,
}

/// How the reject delay is counted.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DelayUnit {
    /// Microseconds after the verdict.
    Micros,
    /// Lines (the line trigger is the encoder's count) after the rejected one.
    Lines,
}

/// The recipe's scalar settings (the header's fields after the shape).
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct RecipeSettings {
    /// CRC of the calibration blob the recipe was taught with.
    pub calibration_crc: u32,
    /// The user's version number of the recipe.
    pub version: u32,
    /// `d^2` above which a point enters "out of the reference's distribution".
    pub threshold_on: f32,
    /// `d^2` below which a point that was out leaves it (hysteresis).
    pub threshold_off: f32,
    /// Smallest defect in consecutive pixels.
    pub min_pixels: u16,
    /// Smallest defect in consecutive lines (a pixel must be out this many lines).
    pub min_lines: u16,
    /// EWMA weight of each line's mean gloss change.
    pub ewma_lambda: f32,
    /// Drift alarm when `|EWMA|` exceeds this, GU.
    pub ewma_limit: f32,
    /// Reject pulse length, us.
    pub pulse_us: u32,
    /// Reject delay.
    pub delay: u32,
    /// Its unit.
    pub delay_unit: DelayUnit,
    /// Share of a window under which a violation clears.
    pub window_hysteresis: f32,
    /// Per reading, the lowest and highest change from the reference allowed.
    pub windows: [[f32; 2]; READINGS],
    /// Teach quality (informative): see host-tools' teach.
    pub teach_quality: f32,
    /// Lines the reference was taught from.
    pub teach_lines: u32,
    /// Whether a defect's pixels need only be out at the leaving
    /// thresholds, one of them at the entering ones (format 2), or each at
    /// the entering ones (format 1): the rule the thresholds were taught for.
    pub along_line_hysteresis: bool,
}

/// A parsed recipe, read in place.
#[derive(Clone, Copy, Debug)]
pub struct RecipeView<'a> {
    bytes: &'a [u8],
    pixels: usize,
    m: usize,
    groups: usize,
    group_table: usize,
    group_data: usize,
    pixel_data: usize,
    settings: RecipeSettings,
    /// The group and pixel values as f32, when the bytes are 4-byte aligned
    /// (a recipe in a flash slot always is): read with plain loads.
    words: Option<&'a [f32]>,
}

fn u16_at(b: &[u8], o: usize) -> u16 {
    u16::from_le_bytes([b[o], b[o + 1]])
}
fn u32_at(b: &[u8], o: usize) -> u32 {
    u32::from_le_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]])
}
fn f32_at(b: &[u8], o: usize) -> f32 {
    f32::from_bits(u32_at(b, o))
}

/// Values per group for m readings: the packed whitening (of m - 1
/// normalised readings) and the gradient.
pub const fn group_len(m: usize) -> usize {
    (m - 1) * m / 2 + READINGS * m
}

/// Values per pixel for m readings: mean (m), inverse sd (m - 1), the
/// inverse of the means' sum, drift weight.
pub const fn pixel_len(m: usize) -> usize {
    2 * m + 1
}

/// Total recipe length for the shape.
pub const fn recipe_len(pixels: usize, m: usize, groups: usize) -> usize {
    HEADER_LEN + (2 * groups).next_multiple_of(4) + 4 * groups * group_len(m) + 4 * pixels * pixel_len(m) + 4
}

impl<'a> RecipeView<'a> {
    /// Parses and checks a recipe (the bytes without the signature trailer).
    pub fn parse(bytes: &'a [u8]) -> Result<Self, RecipeFault> {
        if bytes.len() < HEADER_LEN + 4 {
            return Err(RecipeFault::TooShort);
        }
        if bytes[0..4] != MAGIC {
            return Err(RecipeFault::BadMagic);
        }
        let format = u16_at(bytes, 4);
        if !(format == FORMAT_VERSION || format == FORMAT_VERSION_ENTERING_RUNS)
            || u16_at(bytes, 6) as usize != HEADER_LEN
        {
            return Err(RecipeFault::UnsupportedVersion);
        }
        let total = u32_at(bytes, 8) as usize;
        if total != bytes.len() {
            return Err(if total > bytes.len() { RecipeFault::TooShort } else { RecipeFault::LengthMismatch });
        }
        if CRC32.checksum(&bytes[..total - 4]) != u32_at(bytes, total - 4) {
            return Err(RecipeFault::CrcMismatch);
        }
        let (pixels, m, groups) = (u16_at(bytes, 16) as usize, u16_at(bytes, 18) as usize, u16_at(bytes, 20) as usize);
        if pixels == 0 || m < 2 {
            return Err(RecipeFault::WrongShape);
        }
        if groups == 0 || groups > MAX_GROUPS || groups > pixels {
            return Err(RecipeFault::BadGroups);
        }
        if recipe_len(pixels, m, groups) != total {
            return Err(RecipeFault::LengthMismatch);
        }
        if u16_at(bytes, 22) != 0 || bytes[57..60] != [0, 0, 0] {
            return Err(RecipeFault::BadValue);
        }
        let group_table = HEADER_LEN;
        let group_data = group_table + (2 * groups).next_multiple_of(4);
        let pixel_data = group_data + 4 * groups * group_len(m);
        let mut prev = 0usize;
        for g in 0..groups {
            let first = u16_at(bytes, group_table + 2 * g) as usize;
            if (g == 0 && first != 0) || (g > 0 && first <= prev) || first >= pixels {
                return Err(RecipeFault::BadGroups);
            }
            prev = first;
        }
        let settings = decode_settings(bytes)?;
        let words = bytemuck::try_cast_slice(&bytes[group_data..total - 4]).ok();
        let view = Self { bytes, pixels, m, groups, group_table, group_data, pixel_data, settings, words };
        // Every per-group and per-pixel value must be finite: NaN would
        // silently never (or always) reject.
        let values = (total - 4 - group_data) / 4;
        if (0..values).any(|i| !f32_at(bytes, group_data + 4 * i).is_finite()) {
            return Err(RecipeFault::BadValue);
        }
        // A pixel's reference sum divides the line scale's ratios: positive.
        if (0..pixels).any(|p| {
            let sum = view.pixel_value(p, 2 * m - 1);
            sum.is_nan() || sum <= 0.0
        }) {
            return Err(RecipeFault::BadValue);
        }
        Ok(view)
    }

    /// The bytes (without the signature).
    pub fn as_bytes(&self) -> &'a [u8] {
        self.bytes
    }
    /// Pixels P.
    pub fn pixels(&self) -> usize {
        self.pixels
    }
    /// Readings per point m.
    pub fn leds(&self) -> usize {
        self.m
    }
    /// Groups G.
    pub fn groups(&self) -> usize {
        self.groups
    }
    /// The scalar settings.
    pub fn settings(&self) -> &RecipeSettings {
        &self.settings
    }
    /// The recipe's own CRC (its last four bytes): identifies it.
    pub fn crc(&self) -> u32 {
        u32_at(self.bytes, self.bytes.len() - 4)
    }
    /// First pixel of group `g`.
    pub fn group_start(&self, g: usize) -> usize {
        u16_at(self.bytes, self.group_table + 2 * g) as usize
    }
    /// Group `g`'s values (whitening, then gradient) as f32, when the
    /// recipe is 4-byte aligned (else read [`Self::group_bytes`]).
    #[inline]
    pub fn group_words(&self, g: usize) -> Option<&'a [f32]> {
        let at = g * group_len(self.m);
        self.words.map(|w| &w[at..at + group_len(self.m)])
    }
    /// Pixel `p`'s values as f32, when the recipe is 4-byte aligned.
    #[inline]
    pub fn pixel_words(&self, p: usize) -> Option<&'a [f32]> {
        let at = (self.pixel_data - self.group_data) / 4 + p * pixel_len(self.m);
        self.words.map(|w| &w[at..at + pixel_len(self.m)])
    }
    /// Every pixel's values as f32, pixel after pixel ([`pixel_len`]
    /// each), when the recipe is 4-byte aligned: what the decision's loop
    /// walks, with no per-pixel lookup.
    #[inline]
    pub fn pixel_table(&self) -> Option<&'a [f32]> {
        let at = (self.pixel_data - self.group_data) / 4;
        self.words.map(|w| &w[at..at + self.pixels * pixel_len(self.m)])
    }
    /// Group `g`'s values (whitening, then gradient), little-endian f32.
    pub fn group_bytes(&self, g: usize) -> &'a [u8] {
        let at = self.group_data + 4 * g * group_len(self.m);
        &self.bytes[at..at + 4 * group_len(self.m)]
    }
    /// Pixel `p`'s values (mean, inverse sd, drift weight), little-endian f32.
    pub fn pixel_bytes(&self, p: usize) -> &'a [u8] {
        let at = self.pixel_data + 4 * p * pixel_len(self.m);
        &self.bytes[at..at + 4 * pixel_len(self.m)]
    }
    /// Pixel `p`'s value `i` (mean, inverse sd, drift weight).
    pub fn pixel_value(&self, p: usize, i: usize) -> f32 {
        f32_at(self.pixel_bytes(p), 4 * i)
    }
}

fn decode_settings(b: &[u8]) -> Result<RecipeSettings, RecipeFault> {
    let mut windows = [[0.0f32; 2]; READINGS];
    for (r, w) in windows.iter_mut().enumerate() {
        *w = [f32_at(b, 64 + 8 * r), f32_at(b, 68 + 8 * r)];
    }
    let s = RecipeSettings {
        calibration_crc: u32_at(b, 12),
        version: u32_at(b, 24),
        threshold_on: f32_at(b, 28),
        threshold_off: f32_at(b, 32),
        min_pixels: u16_at(b, 36),
        min_lines: u16_at(b, 38),
        ewma_lambda: f32_at(b, 40),
        ewma_limit: f32_at(b, 44),
        pulse_us: u32_at(b, 48),
        delay: u32_at(b, 52),
        delay_unit: match b[56] {
            0 => DelayUnit::Micros,
            1 => DelayUnit::Lines,
            _ => return Err(RecipeFault::BadValue),
        },
        window_hysteresis: f32_at(b, 60),
        windows,
        teach_quality: f32_at(b, 88),
        teach_lines: u32_at(b, 92),
        along_line_hysteresis: u16_at(b, 4) == FORMAT_VERSION,
    };
    check_settings(&s)?;
    Ok(s)
}

/// The settings' own rules (also what the writer refuses).
pub fn check_settings(s: &RecipeSettings) -> Result<(), RecipeFault> {
    let positive = |x: f32| x.is_finite() && x > 0.0;
    let ok = positive(s.threshold_on)
        && positive(s.threshold_off)
        && s.threshold_off <= s.threshold_on
        && s.min_pixels >= 1
        && s.min_lines >= 1
        && positive(s.ewma_lambda)
        && s.ewma_lambda <= 1.0
        && positive(s.ewma_limit)
        && s.pulse_us > 0
        && positive(s.window_hysteresis)
        && s.window_hysteresis <= 1.0
        && s.windows.iter().all(|[lo, hi]| *lo <= 0.0 && *hi >= 0.0 && *lo < *hi);
    if ok { Ok(()) } else { Err(RecipeFault::BadValue) }
}

/// Everything a recipe holds, as the host builds it.
#[cfg(any(test, feature = "std"))]
#[derive(Clone, Debug, PartialEq)]
pub struct RecipeData {
    /// Pixels P.
    pub pixels: usize,
    /// Readings per point m.
    pub m: usize,
    /// First pixel of each group.
    pub group_starts: Vec<u16>,
    /// Per group, [`group_len`] values.
    pub group_values: Vec<Vec<f32>>,
    /// Per pixel, [`pixel_len`] values.
    pub pixel_values: Vec<Vec<f32>>,
    /// The scalar settings.
    pub settings: RecipeSettings,
}

/// Writes a recipe (unsigned: sign it with [`crate::signed::sign`]). The
/// result parses, or this fails with the reason it would not.
#[cfg(any(test, feature = "std"))]
pub fn write(d: &RecipeData) -> Result<Vec<u8>, RecipeFault> {
    let (p, m, g) = (d.pixels, d.m, d.group_starts.len());
    if d.pixel_values.len() != p
        || d.group_values.len() != g
        || d.pixel_values.iter().any(|v| v.len() != pixel_len(m))
        || d.group_values.iter().any(|v| v.len() != group_len(m))
        || p > u16::MAX as usize
        || m > u16::MAX as usize
    {
        return Err(RecipeFault::WrongShape);
    }
    check_settings(&d.settings)?;
    let s = &d.settings;
    let total = recipe_len(p, m, g);
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(&MAGIC);
    let format = if s.along_line_hysteresis { FORMAT_VERSION } else { FORMAT_VERSION_ENTERING_RUNS };
    out.extend_from_slice(&format.to_le_bytes());
    out.extend_from_slice(&(HEADER_LEN as u16).to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&s.calibration_crc.to_le_bytes());
    out.extend_from_slice(&(p as u16).to_le_bytes());
    out.extend_from_slice(&(m as u16).to_le_bytes());
    out.extend_from_slice(&(g as u16).to_le_bytes());
    out.extend_from_slice(&0u16.to_le_bytes());
    out.extend_from_slice(&s.version.to_le_bytes());
    for x in [s.threshold_on, s.threshold_off] {
        out.extend_from_slice(&x.to_le_bytes());
    }
    out.extend_from_slice(&s.min_pixels.to_le_bytes());
    out.extend_from_slice(&s.min_lines.to_le_bytes());
    for x in [s.ewma_lambda, s.ewma_limit] {
        out.extend_from_slice(&x.to_le_bytes());
    }
    out.extend_from_slice(&s.pulse_us.to_le_bytes());
    out.extend_from_slice(&s.delay.to_le_bytes());
    out.push(match s.delay_unit {
        DelayUnit::Micros => 0,
        DelayUnit::Lines => 1,
    });
    out.extend_from_slice(&[0, 0, 0]);
    out.extend_from_slice(&s.window_hysteresis.to_le_bytes());
    for [lo, hi] in s.windows {
        out.extend_from_slice(&lo.to_le_bytes());
        out.extend_from_slice(&hi.to_le_bytes());
    }
    out.extend_from_slice(&s.teach_quality.to_le_bytes());
    out.extend_from_slice(&s.teach_lines.to_le_bytes());
    debug_assert_eq!(out.len(), HEADER_LEN);
    for start in &d.group_starts {
        out.extend_from_slice(&start.to_le_bytes());
    }
    out.resize(HEADER_LEN + (2 * g).next_multiple_of(4), 0);
    for x in d.group_values.iter().chain(&d.pixel_values).flatten() {
        out.extend_from_slice(&x.to_le_bytes());
    }
    let crc = CRC32.checksum(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    RecipeView::parse(&out)?;
    Ok(out)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    pub(crate) fn settings() -> RecipeSettings {
        RecipeSettings {
            calibration_crc: 0x1234_5678,
            version: 3,
            threshold_on: 40.0,
            threshold_off: 30.0,
            min_pixels: 2,
            min_lines: 1,
            ewma_lambda: 0.1,
            ewma_limit: 1.5,
            pulse_us: 25_000,
            delay: 2,
            delay_unit: DelayUnit::Lines,
            window_hysteresis: 0.8,
            windows: [[-2.0, 2.0], [-1.0, 1.0], [f32::NEG_INFINITY, f32::INFINITY]],
            teach_quality: 2.5,
            teach_lines: 200,
            along_line_hysteresis: true,
        }
    }

    fn data() -> RecipeData {
        let m = 3;
        RecipeData {
            pixels: 6,
            m,
            group_starts: vec![0, 4],
            group_values: vec![(0..group_len(m)).map(|i| i as f32).collect(); 2],
            pixel_values: (0..6).map(|p| (0..pixel_len(m)).map(|i| (p * 10 + i) as f32).collect()).collect(),
            settings: settings(),
        }
    }

    #[test]
    fn round_trips_every_field() {
        let bytes = write(&data()).unwrap();
        assert_eq!(bytes.len(), recipe_len(6, 3, 2));
        let v = RecipeView::parse(&bytes).unwrap();
        assert_eq!((v.pixels(), v.leds(), v.groups()), (6, 3, 2));
        assert_eq!(*v.settings(), settings());
        assert_eq!((v.group_start(0), v.group_start(1)), (0, 4));
        assert_eq!(v.group_bytes(1)[20..24], 5.0f32.to_le_bytes());
        assert_eq!(v.pixel_value(4, 6), 46.0);
        assert_eq!(v.crc(), CRC32.checksum(&bytes[..bytes.len() - 4]));
    }

    #[test]
    fn a_format_1_recipe_is_read_with_the_rule_it_was_taught_for() {
        let mut d = data();
        d.settings.along_line_hysteresis = false;
        let bytes = write(&d).unwrap();
        assert_eq!(u16_at(&bytes, 4), FORMAT_VERSION_ENTERING_RUNS);
        assert_eq!(*RecipeView::parse(&bytes).unwrap().settings(), d.settings);
        assert_eq!(u16_at(&write(&data()).unwrap(), 4), FORMAT_VERSION);
        // A format this firmware does not know is refused as such.
        let mut later = bytes.clone();
        later[4..6].copy_from_slice(&(FORMAT_VERSION + 1).to_le_bytes());
        assert_eq!(RecipeView::parse(&later).unwrap_err(), RecipeFault::UnsupportedVersion);
    }

    #[test]
    fn every_corruption_is_refused_with_its_reason() {
        let good = write(&data()).unwrap();
        for i in 0..good.len() {
            let mut b = good.clone();
            b[i] ^= 0x10;
            assert!(RecipeView::parse(&b).is_err(), "byte {i} flipped was accepted");
        }
        assert_eq!(RecipeView::parse(&good[..50]).unwrap_err(), RecipeFault::TooShort);
        assert_eq!(RecipeView::parse(&good[..good.len() - 4]).unwrap_err(), RecipeFault::TooShort);
        let mut d = data();
        d.settings.threshold_off = 50.0;
        assert_eq!(write(&d).unwrap_err(), RecipeFault::BadValue);
        let mut d = data();
        d.group_starts = vec![0, 0];
        assert_eq!(write(&d).unwrap_err(), RecipeFault::BadGroups);
        let mut d = data();
        d.pixel_values[2][1] = f32::NAN;
        assert_eq!(write(&d).unwrap_err(), RecipeFault::BadValue);
        let mut d = data();
        d.settings.windows[0] = [1.0, 2.0];
        assert_eq!(write(&d).unwrap_err(), RecipeFault::BadValue);
    }
}
