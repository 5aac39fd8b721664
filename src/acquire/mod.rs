//! The acquisition pipeline: for each line, a dark frame and one frame per LED
//! in the calibrated order, then dark subtraction, white calibration (per pixel
//! and LED) and per-point quality flags.
//!
//! A frame that saturates is taken again at each of up to
//! [`MAX_SHORT_EXPOSURES`] shorter exposures, while it still saturates (a
//! dark frame at each exposure first): a mirror-like sample reflects an LED
//! straight into a pixel, tens to hundreds of times brighter than a white
//! diffuser, and one exposure long enough for a dark matt sample cannot hold
//! it. A saturated reading is then taken from its longest unsaturated
//! exposure, scaled by the exposures' ratio (exact: integer microseconds).
//!
//! With the calibration's [`Linearity`] each exposure's dark-corrected
//! signal is made linear before it is scaled and white-calibrated
//! ([`linearity`]).
//!
//! [`correct_reading`] is the one definition of a corrected reading: the
//! device runs it on each frame while the next one's LED settles
//! ([`by_frame`]), the benchmarks and tools on a whole recorded line
//! ([`correct_line`]), and the host point by point ([`correct_point_into`])
//! to reproduce the device's numbers bit for bit.
//!
//! Where it lives: this file, the line's frames, the correction and
//! `acquire_line`; [`by_frame`], the correction as the frames arrive;
//! [`linearity`], the sensor's linearity correction.
pub mod by_frame;
pub mod linearity;

pub use by_frame::{FrameRead, LineCorrection};
pub use linearity::Linearity;

use crate::protocol::flags;
use nalgebra::SVector;

/// Dark-corrected signal (counts) below which a reading is flagged
/// under-exposed: a few LSB of a 12-bit converter, where quantisation and dark
/// noise dominate.
pub const MIN_SIGNAL_COUNTS: f32 = 8.0;

/// Most shorter exposures taken of a frame that saturates.
pub const MAX_SHORT_EXPOSURES: usize = 2;

/// Raw frames of one line: the dark frame and, for each reading i, the frame
/// taken with LED `led_order[i]` lit; and the shorter exposures' frames.
#[derive(Clone)]
pub struct RawLine<const M: usize, const P: usize> {
    /// Dark frame.
    pub dark: [u16; P],
    /// Frame of reading i (reading order, not LED index).
    pub lit: [[u16; P]; M],
    /// Per shorter exposure, its dark frame (valid when any frame was taken at it).
    pub short_dark: [[u16; P]; MAX_SHORT_EXPOSURES],
    /// Per shorter exposure and reading, the frame (valid where `short_taken`).
    pub short: [[[u16; P]; M]; MAX_SHORT_EXPOSURES],
    /// Which shorter frames were taken.
    pub short_taken: [[bool; M]; MAX_SHORT_EXPOSURES],
}

impl<const M: usize, const P: usize> RawLine<M, P> {
    /// All zeros, no shorter frame taken.
    pub const fn new() -> Self {
        Self {
            dark: [0; P],
            lit: [[0; P]; M],
            short_dark: [[0; P]; MAX_SHORT_EXPOSURES],
            short: [[[0; P]; M]; MAX_SHORT_EXPOSURES],
            short_taken: [[false; M]; MAX_SHORT_EXPOSURES],
        }
    }

    /// Whether reading `i` needs its frame at shorter exposure `level`:
    /// its frame at the exposure before (the long one for level 0) was
    /// taken and saturated somewhere. The exposure ladder's one rule, which
    /// the acquisition follows and a benchmark's replay of a line repeats.
    #[inline(always)]
    pub fn needs_shorter(&self, level: usize, i: usize, full_scale: u16) -> bool {
        let longer = if level == 0 {
            Some(&self.lit[i])
        } else {
            self.short_taken[level - 1][i].then_some(&self.short[level - 1][i])
        };
        longer.is_some_and(|f| f.iter().any(|x| *x >= full_scale))
    }

    /// A line from recorded frames, little-endian u16: per exposure level
    /// (the long one, then `shorter` of the shorter ones, every frame of
    /// which counts as taken) the dark frame, then one frame per reading,
    /// each `P` values. How the benchmarks replay lines the host recorded.
    ///
    /// # Panics
    /// As [`Self::read_le_frames`].
    pub fn from_le_frames(frames: &[u8], shorter: usize) -> Self {
        let mut raw = Self::new();
        raw.read_le_frames(frames, shorter);
        raw
    }

    /// Makes this line the one `frames` records ([`Self::from_le_frames`]),
    /// in place: a bench replays lines into a static, where a line built
    /// as a value (6 KB with P = 128) would pass through its stack.
    ///
    /// # Panics
    /// If `shorter > MAX_SHORT_EXPOSURES` or `frames` holds fewer than
    /// `2 P (M + 1) (1 + shorter)` bytes.
    pub fn read_le_frames(&mut self, frames: &[u8], shorter: usize) {
        assert!(shorter <= MAX_SHORT_EXPOSURES, "at most {MAX_SHORT_EXPOSURES} shorter exposures");
        assert!(frames.len() >= 2 * P * (M + 1) * (1 + shorter), "too few bytes for the line's frames");
        let px = |f: usize, p: usize| u16::from_le_bytes([frames[2 * (f * P + p)], frames[2 * (f * P + p) + 1]]);
        for (l, taken) in self.short_taken.iter_mut().enumerate() {
            *taken = [l < shorter; M];
        }
        for p in 0..P {
            self.dark[p] = px(0, p);
            for i in 0..M {
                self.lit[i][p] = px(1 + i, p);
            }
            for l in 0..shorter {
                let base = (l + 1) * (M + 1);
                self.short_dark[l][p] = px(base, p);
                for i in 0..M {
                    self.short[l][i][p] = px(base + 1 + i, p);
                }
            }
        }
    }
}

/// One point at a shorter exposure: the dark frame's value, the ratio of
/// the long exposure to this one, and the point's values in reading order.
#[derive(Clone, Copy, Debug)]
pub struct Shorter<'a> {
    /// The dark frame's value at this exposure.
    pub dark: u16,
    /// Long exposure over this one.
    pub ratio: f32,
    /// The lit frames' values, reading order.
    pub lit: &'a [u16],
    /// Which readings' frames were taken at this exposure (a saturated
    /// reading whose frame was not taken, because the sensor had none to
    /// give, stays saturated).
    pub taken: &'a [bool],
}

impl<const M: usize, const P: usize> Default for RawLine<M, P> {
    fn default() -> Self {
        Self::new()
    }
}

/// Corrects one point: `v[i] = (lit[i] - dark) / white[i]`, in f32, and flags
/// saturation (a raw value at full scale), under-exposure (signal below
/// [`MIN_SIGNAL_COUNTS`]) and non-finite results. Fixed-size form of
/// [`correct_point_into`] without shorter exposures or a linearity
/// correction (same operations, same bits).
#[inline]
pub fn correct_point<const M: usize>(dark: u16, lit: &[u16; M], white: &[f32; M], full_scale: u16) -> ([f32; M], u8) {
    let mut v = [0.0f32; M];
    let f = correct_point_into(dark, lit, white, full_scale, &[], None, &mut v);
    (v, f)
}

/// Corrects one point of `lit.len()` readings into `v`; returns its flags.
/// A reading whose long frame saturated is taken from the first of
/// `shorter` (longest first) whose frame did not, `(lit - dark) ratio /
/// white`; it is flagged saturated only when the shortest saturated too (or
/// there is none). With `linearity`, each exposure's `lit - dark` is made
/// linear first ([`Linearity::linear`]); the under-exposure test is on the
/// counts as read. Each reading is [`correct_reading`]'s, as the device's
/// [`correct_line`] makes it; the host uses this to reproduce the device's
/// numbers.
///
/// # Panics
/// If `lit`, `white`, `v` and every shorter exposure's `lit` differ in length.
#[inline]
pub fn correct_point_into(
    dark: u16,
    lit: &[u16],
    white: &[f32],
    full_scale: u16,
    shorter: &[Shorter<'_>],
    linearity: Option<&Linearity>,
    v: &mut [f32],
) -> u8 {
    assert!(lit.len() == white.len() && lit.len() == v.len(), "one white value and one output per reading");
    assert!(
        shorter.iter().all(|s| s.lit.len() == lit.len() && s.taken.len() == lit.len()),
        "one value per reading at every exposure"
    );
    // Without a correction the identity's, which changes no bit: one path,
    // not a copy of the loop per case.
    let lin = linearity.unwrap_or(&Linearity::IDENTITY);
    let mut f = dark_flags(dark, full_scale);
    for i in 0..v.len() {
        let (x, fi) = correct_reading(dark, lit[i], white[i], full_scale, lin, shorter.len(), |l| {
            let e = &shorter[l];
            e.taken[i].then(|| (e.lit[i], e.dark, e.ratio))
        });
        v[i] = x;
        f |= fi;
    }
    f
}

/// A point's flags from its dark value alone: saturated when the dark frame is.
#[inline(always)]
fn dark_flags(dark: u16, full_scale: u16) -> u8 {
    if dark >= full_scale { flags::SATURATED } else { 0 }
}

/// The one definition of a corrected reading: `(lit - dark)` made linear
/// and divided by `white`, or, when `lit` is at `full_scale`, the first of
/// the `levels` shorter exposures (`short(l)`: its value, its dark value
/// and the long exposure over it, `None` where its frame was not taken)
/// that did not saturate, made linear and scaled by its ratio; and the
/// reading's flags (under-exposed on the long exposure's counts; saturated
/// when every exposure taken was; not finite). Only the signal a reading
/// is taken from is made linear, once: the saturated long signal of a
/// reading replaced by a shorter one never is (on a glossy line most are).
#[inline(always)]
pub fn correct_reading(
    dark: u16,
    lit: u16,
    white: f32,
    full_scale: u16,
    lin: &Linearity,
    levels: usize,
    short: impl Fn(usize) -> Option<(u16, u16, f32)>,
) -> (f32, u8) {
    let mut f = 0u8;
    let counts = lit as f32 - dark as f32;
    if counts < MIN_SIGNAL_COUNTS {
        f |= flags::UNDER_EXPOSED;
    }
    let mut saturated = lit >= full_scale;
    // The signal the reading is taken from, and its exposure's ratio: the
    // long exposure's (ratio 1: `x * 1.0` is `x`, bit for bit), or the
    // first shorter one that did not saturate (else the shortest taken).
    // One linearisation, after the ladder.
    let (mut signal, mut ratio) = (counts, 1.0f32);
    for l in 0..levels {
        if !saturated {
            break;
        }
        let Some((s_lit, s_dark, r)) = short(l) else { break };
        (signal, ratio) = (s_lit as f32 - s_dark as f32, r);
        saturated = s_lit >= full_scale;
    }
    let s = lin.linear(signal) * ratio;
    if saturated {
        f |= flags::SATURATED;
    }
    let x = s / white;
    if !x.is_finite() {
        f |= flags::NON_FINITE;
    }
    (x, f)
}

/// Corrects a whole line into `v` and `fl` (one entry per pixel), its
/// shorter exposures taken at `cfg.short_exposures_us`, made linear by
/// `linearity` when the calibration has one: every reading
/// [`correct_reading`]'s, frame by frame (the order the frames are read
/// in and are laid out).
pub fn correct_line<const M: usize, const P: usize>(
    raw: &RawLine<M, P>,
    white: &[[f32; M]; P],
    linearity: Option<&Linearity>,
    full_scale: u16,
    cfg: &AcqConfig,
    v: &mut [SVector<f32, M>; P],
    fl: &mut [u8; P],
) {
    let k = Exposures::new(linearity, cfg);
    for (f, d) in fl.iter_mut().zip(&raw.dark) {
        *f = dark_flags(*d, full_scale);
    }
    for i in 0..M {
        for p in 0..P {
            let (x, f) = k.reading(raw, i, p, white[p][i], full_scale);
            v[p][i] = x;
            fl[p] |= f;
        }
    }
}

/// What a line's readings are corrected with, worked out once (a line, or
/// a frame), not once a reading: the linearity (the identity's without
/// one), the shorter exposures configured and their ratios.
pub(crate) struct Exposures<'a> {
    lin: &'a Linearity,
    levels: usize,
    ratios: [f32; MAX_SHORT_EXPOSURES],
}

impl<'a> Exposures<'a> {
    pub(crate) fn new(linearity: Option<&'a Linearity>, cfg: &AcqConfig) -> Self {
        let levels = cfg.short_levels();
        Self {
            lin: linearity.unwrap_or(&Linearity::IDENTITY),
            levels,
            ratios: core::array::from_fn(|l| if l < levels { cfg.ratio(l) } else { 0.0 }),
        }
    }

    /// How many shorter exposures are configured.
    pub(crate) fn levels(&self) -> usize {
        self.levels
    }

    /// Reading `i` of pixel `p` of `raw`, [`correct_reading`]'s.
    #[inline(always)]
    pub(crate) fn reading<const M: usize, const P: usize>(
        &self,
        raw: &RawLine<M, P>,
        i: usize,
        p: usize,
        white: f32,
        full_scale: u16,
    ) -> (f32, u8) {
        correct_reading(raw.dark[p], raw.lit[i][p], white, full_scale, self.lin, self.levels, |l| {
            raw.short_taken[l][i].then(|| (raw.short[l][i][p], raw.short_dark[l][p], self.ratios[l]))
        })
    }
}

/// Timing and drive of an acquisition.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AcqConfig {
    /// Sensor integration time per frame.
    pub exposure_us: u32,
    /// Wait after switching LEDs before integrating.
    pub settle_us: u32,
    /// LED drive, 0..=u16::MAX.
    pub intensity: u16,
    /// The shorter exposures taken of a frame that saturates, longest first
    /// (each shorter than the one before; a 0 ends the list).
    pub short_exposures_us: [u32; MAX_SHORT_EXPOSURES],
}

impl AcqConfig {
    /// How many shorter exposures are configured.
    pub fn short_levels(&self) -> usize {
        self.short_exposures_us.iter().take_while(|e| **e > 0).count()
    }

    /// The long exposure over shorter exposure `level`.
    pub fn ratio(&self, level: usize) -> f32 {
        self.exposure_us as f32 / self.short_exposures_us[level] as f32
    }

    /// The exposure level of a frame integrated for `exposure_us` (0: the
    /// long exposure, 1 + l: shorter exposure l), as a simulated sensor
    /// tells which frame to serve.
    pub fn level_of(&self, exposure_us: u32) -> usize {
        self.short_exposures_us[..self.short_levels()].iter().position(|e| *e == exposure_us).map_or(0, |l| l + 1)
    }
}

impl Default for AcqConfig {
    fn default() -> Self {
        Self { exposure_us: 500, settle_us: 50, intensity: u16::MAX, short_exposures_us: [0; MAX_SHORT_EXPOSURES] }
    }
}

/// What the acquisition does beside reading a line's frames, in the time
/// the line waits anyway.
#[cfg(feature = "app")]
pub trait FrameWork<const M: usize, const P: usize> {
    /// Told of each frame read once the next LED is switched and its
    /// settling time started; runs while it settles (the settle is a
    /// deadline set before it, so work shorter than the settle costs the
    /// line nothing): the acquisition task corrects the frame there
    /// ([`LineCorrection`]). The last frame's call comes after the LEDs are
    /// off, before [`acquire_line`] returns; a frame whose read failed is
    /// not told.
    fn read(&mut self, f: FrameRead, raw: &RawLine<M, P>);

    /// Runs while LED frame `f` integrates (the sensor's read has started
    /// its exposure and waits for it): work shorter than the exposure
    /// costs the line nothing. The inspection works out the first part of
    /// its decision here, while the line's last LED frame integrates.
    fn integrating(&mut self, f: FrameRead) {
        let _ = f;
    }
}

#[cfg(feature = "app")]
impl<F: FnMut(FrameRead, &RawLine<M, P>), const M: usize, const P: usize> FrameWork<M, P> for F {
    fn read(&mut self, f: FrameRead, raw: &RawLine<M, P>) {
        self(f, raw)
    }
}

/// Reads one line's frames: dark, then one frame per reading with LED
/// `order[i]` lit, and for each shorter exposure while a frame still
/// saturates, that frame again (after a dark frame at that exposure, once a
/// line). In two passes: the first m - 1 readings, then the last. So every
/// other reading is final before the last LED's long frame integrates, and
/// the inspection works out the first part of its decision then
/// ([`FrameWork::integrating`]); the frames are the same, and as many, as
/// in one pass. The LEDs are off when this returns, error or not. `work`
/// runs between (see [`FrameWork`]).
#[cfg(feature = "app")]
pub async fn acquire_line<L: crate::hw::Leds, S: crate::hw::LineSensor, const M: usize, const P: usize>(
    leds: &mut L,
    sensor: &mut S,
    order: &[u8; M],
    cfg: &AcqConfig,
    raw: &mut RawLine<M, P>,
    work: &mut impl FrameWork<M, P>,
) -> Result<(), crate::hw::SensorError> {
    use embassy_futures::join::join;
    use embassy_time::Timer;
    // The frame read last, not yet told.
    let mut pending: Option<FrameRead> = None;
    // Starts the settling time, tells the pending frame, then waits out the rest.
    macro_rules! settle {
        () => {{
            let t = Timer::after_micros(cfg.settle_us as u64);
            if let Some(f) = pending.take() {
                work.read(f, raw);
            }
            t.await;
        }};
    }
    // Reads an LED frame, with the work for its exposure: the read is
    // polled first, so the exposure has started when the work runs.
    macro_rules! read_lit {
        ($exposure:expr, $into:expr, $f:expr) => {{
            let f = $f;
            join(sensor.read_frame($exposure, $into), async { work.integrating(f) }).await.0
        }};
    }
    let fs = sensor.full_scale();
    raw.short_taken = [[false; M]; MAX_SHORT_EXPOSURES];
    leds.set(None, 0).await;
    settle!();
    let mut r = sensor.read_frame(cfg.exposure_us, &mut raw.dark).await;
    if r.is_ok() {
        pending = Some(FrameRead::Dark);
    }
    // A dark frame per shorter exposure, once a line (bit `level` once
    // taken); none after a simulated sensor said it has no frames at one.
    let mut dark_taken = 0u8;
    let mut shorter = true;
    for pass in [0..M.saturating_sub(1), M.saturating_sub(1)..M] {
        for i in pass.clone() {
            if r.is_err() {
                break;
            }
            leds.set(Some(order[i]), cfg.intensity).await;
            settle!();
            r = read_lit!(cfg.exposure_us, &mut raw.lit[i], FrameRead::Long(i));
            if r.is_ok() {
                pending = Some(FrameRead::Long(i));
            }
        }
        let levels = if shorter { cfg.short_levels() } else { 0 };
        'ladder: for level in 0..levels {
            if r.is_err() {
                break;
            }
            let exposure = cfg.short_exposures_us[level];
            for i in pass.clone() {
                if !raw.needs_shorter(level, i, fs) {
                    continue;
                }
                if dark_taken & (1 << level) == 0 {
                    leds.set(None, 0).await;
                    settle!();
                    r = sensor.read_frame(exposure, &mut raw.short_dark[level]).await;
                    dark_taken |= 1 << level;
                }
                // The lit frame once the dark one is there; one outcome for both.
                if r.is_ok() {
                    leds.set(Some(order[i]), cfg.intensity).await;
                    settle!();
                    r = read_lit!(exposure, &mut raw.short[level][i], FrameRead::Short { level, reading: i });
                }
                if r == Err(crate::hw::SensorError::NoData) {
                    // A simulated sensor without frames at this exposure:
                    // the line goes on with what it has (saturated stays so).
                    r = Ok(());
                    shorter = false;
                    break 'ladder;
                }
                if r.is_err() {
                    break;
                }
                raw.short_taken[level][i] = true;
                pending = Some(FrameRead::Short { level, reading: i });
            }
        }
    }
    leds.set(None, 0).await;
    if let (Ok(()), Some(f)) = (r, pending) {
        work.read(f, raw);
    }
    r
}

/// Lines of random frames with every case a reading meets, for the
/// correction's tests.
#[cfg(test)]
pub(crate) mod test_lines {
    use super::*;

    /// A small deterministic generator (xorshift32).
    pub struct Xorshift(pub u32);

    impl Xorshift {
        /// A value in `0..n`.
        pub fn below(&mut self, n: u32) -> u32 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 17;
            self.0 ^= self.0 << 5;
            self.0 % n
        }
    }

    /// A linearity correction that bends every octave.
    pub fn linearity() -> Linearity {
        Linearity::new(core::array::from_fn(|k| 1.0 + 0.004 * (16 - k) as f32)).unwrap()
    }

    /// Two shorter exposures, 16 and 80 times shorter.
    pub fn config() -> AcqConfig {
        AcqConfig { exposure_us: 800, short_exposures_us: [50, 10], ..AcqConfig::default() }
    }

    /// A line of random frames at full scale `fs`: some dark values
    /// saturated, a quarter of the readings under-exposed and a quarter
    /// saturated (none of reading `calm`), a third of the shorter frames'
    /// values saturated; no shorter frame marked taken.
    pub fn random_line<const M: usize, const P: usize>(
        rng: &mut Xorshift,
        fs: u16,
        calm: Option<usize>,
    ) -> RawLine<M, P> {
        let mut raw = RawLine::<M, P>::new();
        for p in 0..P {
            raw.dark[p] = if rng.below(50) == 0 { fs } else { 40 + rng.below(30) as u16 };
            for l in 0..MAX_SHORT_EXPOSURES {
                raw.short_dark[l][p] = 40 + rng.below(30) as u16;
            }
            for i in 0..M {
                raw.lit[i][p] = match rng.below(4) {
                    _ if calm == Some(i) => 50 + rng.below(3000) as u16,
                    0 => 30 + rng.below(20) as u16,
                    1 => fs,
                    _ => 50 + rng.below(4046) as u16,
                };
                for l in 0..MAX_SHORT_EXPOSURES {
                    raw.short[l][i][p] = if rng.below(3) == 0 { fs } else { 45 + rng.below(4050) as u16 };
                }
            }
        }
        raw
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recorded_frames_replay_as_the_line_they_were() {
        // Two readings, three pixels, one shorter exposure: value = 100 f + p.
        let mut bytes = [0u8; 2 * 3 * 3 * 2];
        for f in 0..6 {
            for p in 0..3 {
                bytes[2 * (f * 3 + p)..][..2].copy_from_slice(&((100 * f + p) as u16).to_le_bytes());
            }
        }
        let raw = RawLine::<2, 3>::from_le_frames(&bytes, 1);
        assert_eq!((raw.dark, raw.lit), ([0, 1, 2], [[100, 101, 102], [200, 201, 202]]));
        assert_eq!((raw.short_dark[0], raw.short[0]), ([300, 301, 302], [[400, 401, 402], [500, 501, 502]]));
        assert_eq!(raw.short_taken, [[true, true], [false, false]]);
        let long_only = RawLine::<2, 3>::from_le_frames(&bytes[..2 * 3 * 3], 0);
        assert_eq!((long_only.lit, long_only.short_taken), (raw.lit, [[false; 2]; MAX_SHORT_EXPOSURES]));
        // Replayed in place over a line that had a shorter exposure, the
        // shorter frames are no longer taken.
        let mut reused = raw.clone();
        reused.read_le_frames(&bytes[..2 * 3 * 3], 0);
        assert_eq!((reused.dark, reused.lit, reused.short_taken), (raw.dark, raw.lit, long_only.short_taken));
    }

    #[test]
    fn corrects_and_flags() {
        let white = [1000.0f32, 500.0, 250.0];
        let (v, f) = correct_point(100, &[1100, 600, 350], &white, 4095);
        assert_eq!(v, [1.0, 1.0, 1.0]);
        assert_eq!(f, 0);
        let (_, f) = correct_point(100, &[4095, 600, 350], &white, 4095);
        assert_eq!(f, flags::SATURATED);
        let (v, f) = correct_point(100, &[1100, 104, 350], &white, 4095);
        assert_eq!(f, flags::UNDER_EXPOSED);
        assert_eq!(v[1], 4.0 / 500.0);
        let (_, f) = correct_point(4095, &[4095, 4095, 4095], &white, 4095);
        assert_eq!(f, flags::SATURATED | flags::UNDER_EXPOSED);
        let (_, f) = correct_point(0, &[10, 10, 10], &[f32::MIN_POSITIVE, 1.0, 1.0], 4095);
        assert_eq!(f & flags::NON_FINITE, flags::NON_FINITE);
    }

    #[test]
    fn a_saturated_reading_comes_from_its_longest_unsaturated_exposure() {
        let white = [1000.0f32, 500.0];
        let fs = 4095;
        // Reading 0 saturates the long exposure and the first shorter one
        // (ratio 16), not the second (ratio 80); reading 1 saturates nothing.
        let s16 = Shorter { dark: 7, ratio: 16.0, lit: &[4095, 99], taken: &[true, false] };
        let s80 = Shorter { dark: 5, ratio: 80.0, lit: &[1005, 99], taken: &[true, false] };
        let mut v = [0.0f32; 2];
        let f = correct_point_into(100, &[4095, 600], &white, fs, &[s16, s80], None, &mut v);
        assert_eq!(f, 0);
        assert_eq!(v, [(1005.0 - 5.0) * 80.0 / 1000.0, 500.0 / 500.0]);
        // Only the first shorter exposure configured: still saturated.
        let f = correct_point_into(100, &[4095, 600], &white, fs, &[s16], None, &mut v);
        assert_eq!(f, flags::SATURATED);
        // A shorter frame the sensor could not give: saturated stays so.
        let none = Shorter { taken: &[false, false], ..s16 };
        let f = correct_point_into(100, &[4095, 600], &white, fs, &[none, s80], None, &mut v);
        assert_eq!((f, v[0]), (flags::SATURATED, 3995.0 / 1000.0));
        let cfg = AcqConfig { exposure_us: 2000, short_exposures_us: [125, 25], ..AcqConfig::default() };
        assert_eq!((cfg.short_levels(), cfg.ratio(0), cfg.ratio(1)), (2, 16.0, 80.0));
        assert_eq!((cfg.level_of(2000), cfg.level_of(125), cfg.level_of(25)), (0, 1, 2));
    }

    #[test]
    fn each_exposure_is_made_linear_before_it_is_scaled() {
        // A correction of 1.25 below 2^8 counts and 1 from 2^9 up.
        let mut f = [1.0f32; linearity::LINEARITY_KNOTS];
        f[..=8].fill(1.25);
        let lin = Linearity::new(f).unwrap();
        let white = [1000.0f32, 500.0];
        let s16 = Shorter { dark: 7, ratio: 16.0, lit: &[107, 99], taken: &[true, false] };
        let mut v = [0.0f32; 2];
        // Reading 0 saturates and is read at 1/16 (100 counts, x 1.25);
        // reading 1's 5 counts are under-exposed as read, and corrected too.
        let f = correct_point_into(100, &[4095, 105], &white, 4095, &[s16], Some(&lin), &mut v);
        assert_eq!(f, flags::UNDER_EXPOSED);
        assert_eq!(v, [100.0 * 1.25 * 16.0 / 1000.0, 5.0 * 1.25 / 500.0]);
        // Without it, the same frames read as before.
        correct_point_into(100, &[4095, 105], &white, 4095, &[s16], None, &mut v);
        assert_eq!(v, [100.0 * 16.0 / 1000.0, 5.0 / 500.0]);
    }

    /// The correction as it was first written, reading by reading: the long
    /// exposure always made linear, then replaced while a shorter one was
    /// taken and the last saturated.
    fn correct_as_written(
        dark: u16,
        lit: u16,
        white: f32,
        fs: u16,
        lin: &Linearity,
        short: &[(u16, u16, f32, bool)],
    ) -> (f32, u8) {
        let mut f = if dark >= fs { flags::SATURATED } else { 0 };
        let mut s = lit as f32 - dark as f32;
        let mut saturated = lit >= fs;
        if s < MIN_SIGNAL_COUNTS {
            f |= flags::UNDER_EXPOSED;
        }
        s = lin.linear(s);
        for &(s_lit, s_dark, ratio, taken) in short {
            if !saturated || !taken {
                break;
            }
            s = lin.linear(s_lit as f32 - s_dark as f32) * ratio;
            saturated = s_lit >= fs;
        }
        if saturated {
            f |= flags::SATURATED;
        }
        let x = s / white;
        if !x.is_finite() {
            f |= flags::NON_FINITE;
        }
        (x, f)
    }

    #[test]
    fn line_correction_is_the_correction_as_first_written_bit_for_bit() {
        // Every case a reading meets: under-exposed, saturated with its
        // shorter frames taken or not, saturating at the first shorter
        // exposure too, a saturated dark frame, a zero white value.
        const M: usize = 4;
        const P: usize = 64;
        let fs = 4095u16;
        let (lin, cfg) = (test_lines::linearity(), test_lines::config());
        let mut rng = test_lines::Xorshift(0x2545_f491);
        for line in 0..8 {
            let mut raw = test_lines::random_line::<M, P>(&mut rng, fs, None);
            for i in 0..M {
                raw.short_taken[0][i] = line % 2 == 0 || i % 2 == 0;
                raw.short_taken[1][i] = raw.short_taken[0][i] && i != 1;
            }
            let white: [[f32; M]; P] = core::array::from_fn(|p| {
                core::array::from_fn(|i| if p == 7 && i == 2 { 0.0 } else { 900.0 + (p * M + i) as f32 })
            });
            let mut v = [SVector::<f32, M>::zeros(); P];
            let mut fl = [0u8; P];
            correct_line(&raw, &white, Some(&lin), fs, &cfg, &mut v, &mut fl);
            for p in 0..P {
                let mut want_f = 0;
                for i in 0..M {
                    let short: [(u16, u16, f32, bool); MAX_SHORT_EXPOSURES] = core::array::from_fn(|l| {
                        (raw.short[l][i][p], raw.short_dark[l][p], cfg.ratio(l), raw.short_taken[l][i])
                    });
                    let (x, f) = correct_as_written(raw.dark[p], raw.lit[i][p], white[p][i], fs, &lin, &short);
                    assert_eq!(v[p][i].to_bits(), x.to_bits(), "line {line}, pixel {p}, reading {i}");
                    want_f |= f;
                }
                assert_eq!(fl[p], want_f, "line {line}, pixel {p}");
            }
        }
    }

    #[test]
    fn line_correction_matches_point_correction() {
        let mut raw = RawLine::<2, 3>::new();
        raw.dark = [10, 20, 30];
        raw.lit = [[110, 220, 330], [60, 70, 80]];
        let white = [[100.0, 50.0], [200.0, 25.0], [300.0, 10.0]];
        let mut v = [SVector::<f32, 2>::zeros(); 3];
        let mut fl = [0; 3];
        correct_line(&raw, &white, None, 4095, &AcqConfig::default(), &mut v, &mut fl);
        for p in 0..3 {
            let (vp, f) = correct_point(raw.dark[p], &[raw.lit[0][p], raw.lit[1][p]], &white[p], 4095);
            assert_eq!(v[p], SVector::from(vp));
            assert_eq!(fl[p], f);
        }
    }
}
