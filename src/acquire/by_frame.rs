//! A line corrected frame by frame, while the next frame's LED settles:
//! what is left to correct after a line's last frame is that frame's
//! readings, not the whole line's.
//!
//! Each reading is corrected once, by [`correct_reading`], as soon as no
//! later frame can change it:
//! - a long-exposure reading that did not saturate, or any when no shorter
//!   exposure is configured, when its frame is read;
//! - a saturated one when a shorter exposure of its frame is read at which
//!   it did not saturate, or which is the shortest configured;
//! - any other (a shorter frame the sensor could not give, a line cut short)
//!   by [`LineCorrection::finish`].
//!
//! At that moment [`correct_reading`] sees every exposure the reading's value
//! depends on, and no later one would be consulted, so the line is bit for
//! bit [`correct_line`]'s whatever order the frames came in (a test checks
//! it on lines with every case). The acquisition (`acquire_line`) tells
//! which frame it has just read ([`FrameRead`]) and runs the correction
//! before it waits for the next frame's LED to settle.
use super::{AcqConfig, Exposures, Linearity, MAX_SHORT_EXPOSURES, RawLine, dark_flags};
#[cfg(doc)]
use super::{correct_line, correct_reading};
use nalgebra::SVector;

/// A frame of a line just read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FrameRead {
    /// The long exposure's dark frame (the line's first).
    Dark,
    /// The long exposure of reading `i` (reading order).
    Long(usize),
    /// Shorter exposure `level` of reading `reading`.
    Short {
        /// The exposure level (0: the longest of the shorter ones).
        level: usize,
        /// The reading.
        reading: usize,
    },
}

/// Which readings of the line being acquired are corrected.
pub struct LineCorrection<const M: usize, const P: usize> {
    done: [[bool; P]; M],
    /// Readings not yet corrected: `finish` after a whole line is free.
    pending: usize,
}

impl<const M: usize, const P: usize> Default for LineCorrection<M, P> {
    fn default() -> Self {
        Self::new()
    }
}

/// What a frame's correction reads and writes: the line, its calibration's
/// white values and linearity, the sensor's full scale, the acquisition's
/// settings, and the corrected readings and flags being filled in.
pub struct Target<'a, const M: usize, const P: usize> {
    /// The line's frames.
    pub raw: &'a RawLine<M, P>,
    /// White reference per pixel and reading.
    pub white: &'a [[f32; M]; P],
    /// The sensor's linearity correction, when the calibration has one.
    pub linearity: Option<&'a Linearity>,
    /// Largest raw value.
    pub full_scale: u16,
    /// The exposures.
    pub cfg: &'a AcqConfig,
    /// Corrected readings per pixel.
    pub v: &'a mut [SVector<f32, M>; P],
    /// Flags per pixel.
    pub fl: &'a mut [u8; P],
}

impl<const M: usize, const P: usize> LineCorrection<M, P> {
    /// Nothing corrected.
    pub const fn new() -> Self {
        Self { done: [[false; P]; M], pending: M * P }
    }

    /// Corrects what frame `f`, just read, makes final. The dark frame
    /// starts a line: every reading pending, each pixel's flags its dark
    /// value's.
    pub fn frame(&mut self, f: FrameRead, t: &mut Target<'_, M, P>) {
        let k = Exposures::new(t.linearity, t.cfg);
        match f {
            FrameRead::Dark => {
                self.done = [[false; P]; M];
                self.pending = M * P;
                for (fl, d) in t.fl.iter_mut().zip(&t.raw.dark) {
                    *fl = dark_flags(*d, t.full_scale);
                }
            }
            FrameRead::Long(i) if i < M => {
                // Without shorter exposures the long one is the shortest:
                // saturated or not, nothing later changes its readings.
                // (Two loops: the test stays out of the device's.)
                if k.levels() == 0 {
                    for p in 0..P {
                        self.correct(i, p, t, &k);
                    }
                } else {
                    for p in 0..P {
                        if t.raw.lit[i][p] < t.full_scale {
                            self.correct(i, p, t, &k);
                        }
                    }
                }
            }
            FrameRead::Short { level, reading: i } if i < M && level < MAX_SHORT_EXPOSURES => {
                let last = level + 1 >= k.levels();
                for p in 0..P {
                    if !self.done[i][p] && (last || t.raw.short[level][i][p] < t.full_scale) {
                        self.correct(i, p, t, &k);
                    }
                }
            }
            _ => {}
        }
    }

    /// Corrects every reading still pending: the line is then
    /// [`correct_line`]'s.
    pub fn finish(&mut self, t: &mut Target<'_, M, P>) {
        if self.pending == 0 {
            return;
        }
        let k = Exposures::new(t.linearity, t.cfg);
        for i in 0..M {
            for p in 0..P {
                if !self.done[i][p] {
                    self.correct(i, p, t, &k);
                }
            }
        }
    }

    /// Whether pixel `p`'s first `readings` readings are corrected: no
    /// later frame of the line changes them.
    pub fn final_through(&self, p: usize, readings: usize) -> bool {
        self.done[..readings.min(M)].iter().all(|d| d[p])
    }

    #[inline(always)]
    fn correct(&mut self, i: usize, p: usize, t: &mut Target<'_, M, P>, k: &Exposures<'_>) {
        let (x, f) = k.reading(t.raw, i, p, t.white[p][i], t.full_scale);
        t.v[p][i] = x;
        t.fl[p] |= f;
        if !self.done[i][p] {
            self.done[i][p] = true;
            self.pending -= 1;
        }
    }
}

impl<const M: usize, const P: usize> RawLine<M, P> {
    /// The frames of this recorded line in the order the acquisition reads
    /// them (`acquire_line`): the dark frame, then in two passes (the first
    /// m - 1 readings, then the last) each reading's long exposure, then per
    /// shorter exposure the readings that needed it
    /// ([`RawLine::needs_shorter`]) and whose frame at it was taken. How a
    /// benchmark replays a line through [`LineCorrection`].
    pub fn frames_read(&self, full_scale: u16, levels: usize) -> impl Iterator<Item = FrameRead> + '_ {
        let pass = move |readings: core::ops::Range<usize>| {
            let long = readings.clone().map(FrameRead::Long);
            let short = (0..levels.min(MAX_SHORT_EXPOSURES)).flat_map(move |level| {
                readings.clone().filter_map(move |i| {
                    (self.needs_shorter(level, i, full_scale) && self.short_taken[level][i])
                        .then_some(FrameRead::Short { level, reading: i })
                })
            });
            long.chain(short)
        };
        let last = M.saturating_sub(1);
        core::iter::once(FrameRead::Dark).chain(pass(0..last)).chain(pass(last..M))
    }
}

#[cfg(test)]
mod tests {
    use super::super::{correct_line, test_lines};
    use super::*;

    #[test]
    fn a_line_corrected_frame_by_frame_is_the_line_corrected_whole_bit_for_bit() {
        const M: usize = 4;
        const P: usize = 48;
        let fs = 4095u16;
        let (lin, cfg) = (test_lines::linearity(), test_lines::config());
        let mut rng = test_lines::Xorshift(0x9e37_79b9);
        for line in 0..12 {
            // Reading 3 never saturates: its shorter frames are not taken.
            let mut raw = test_lines::random_line::<M, P>(&mut rng, fs, Some(3));
            // What the acquisition takes: a shorter frame of a reading whose
            // longer one saturated, except where the sensor had none to give
            // (reading 1 at the shortest exposure on odd lines).
            for level in 0..MAX_SHORT_EXPOSURES {
                for i in 0..M {
                    let longer = if level == 0 {
                        Some(&raw.lit[i])
                    } else {
                        raw.short_taken[level - 1][i].then_some(&raw.short[level - 1][i])
                    };
                    raw.short_taken[level][i] =
                        longer.is_some_and(|f| f.iter().any(|x| *x >= fs)) && !(line % 2 == 1 && level == 1 && i == 1);
                }
            }
            let white: [[f32; M]; P] = core::array::from_fn(|p| core::array::from_fn(|i| 800.0 + (p * M + i) as f32));
            let mut want_v = [SVector::<f32, M>::zeros(); P];
            let mut want_fl = [0u8; P];
            correct_line(&raw, &white, Some(&lin), fs, &cfg, &mut want_v, &mut want_fl);
            let (mut v, mut fl) = ([SVector::<f32, M>::from_element(f32::NAN); P], [0xffu8; P]);
            let mut c = LineCorrection::<M, P>::new();
            let frames: heapless::Vec<FrameRead, 16> = raw.frames_read(fs, cfg.short_levels()).collect();
            assert!(frames.iter().any(|f| matches!(f, FrameRead::Short { level: 1, .. })), "line {line}");
            assert!(!frames.contains(&FrameRead::Short { level: 0, reading: 3 }));
            let mut t = Target {
                raw: &raw,
                white: &white,
                linearity: Some(&lin),
                full_scale: fs,
                cfg: &cfg,
                v: &mut v,
                fl: &mut fl,
            };
            // A line cut short at the last frame leaves its readings to `finish`.
            let cut = if line % 3 == 0 { frames.len() - 1 } else { frames.len() };
            for f in &frames[..cut] {
                c.frame(*f, &mut t);
            }
            if cut == frames.len() && line % 2 == 0 {
                // Every frame there was to take was read: nothing is left.
                assert!(c.done.iter().flatten().all(|d| *d), "line {line}");
            } else {
                assert!(!c.done.iter().flatten().all(|d| *d), "line {line}");
            }
            c.finish(&mut t);
            for p in 0..P {
                for i in 0..M {
                    assert_eq!(v[p][i].to_bits(), want_v[p][i].to_bits(), "line {line}, pixel {p}, reading {i}");
                }
                assert_eq!(fl[p], want_fl[p], "line {line}, pixel {p}");
            }
        }
    }

    #[test]
    fn a_frame_corrects_only_what_no_later_frame_changes() {
        let fs = 100u16;
        let cfg = AcqConfig { exposure_us: 100, short_exposures_us: [10, 0], ..AcqConfig::default() };
        let mut raw = RawLine::<1, 3>::new();
        raw.dark = [0; 3];
        raw.lit = [[50, 100, 100]];
        raw.short[0] = [[5, 6, 100]];
        raw.short_taken[0] = [true];
        let white = [[1.0f32]; 3];
        let (mut v, mut fl) = ([SVector::<f32, 1>::zeros(); 3], [0u8; 3]);
        let mut t =
            Target { raw: &raw, white: &white, linearity: None, full_scale: fs, cfg: &cfg, v: &mut v, fl: &mut fl };
        let mut c = LineCorrection::<1, 3>::new();
        c.frame(FrameRead::Dark, &mut t);
        c.frame(FrameRead::Long(0), &mut t);
        assert_eq!(c.done, [[true, false, false]]);
        c.frame(FrameRead::Short { level: 0, reading: 0 }, &mut t);
        // The shortest exposure: saturated there too, it is final all the same.
        assert_eq!(c.done, [[true, true, true]]);
        assert_eq!((t.v[0][0], t.v[1][0], t.fl[2]), (50.0, 60.0, crate::protocol::flags::SATURATED));

        // With no shorter exposure configured, the long one is the
        // shortest: its saturated readings are final at once, and as the
        // whole line's correction gives them.
        let cfg = AcqConfig { exposure_us: 100, short_exposures_us: [0, 0], ..AcqConfig::default() };
        raw.short_taken[0] = [false];
        let (mut v, mut fl) = ([SVector::<f32, 1>::zeros(); 3], [0u8; 3]);
        let (mut want_v, mut want_fl) = ([SVector::<f32, 1>::zeros(); 3], [0u8; 3]);
        super::super::correct_line(&raw, &white, None, fs, &cfg, &mut want_v, &mut want_fl);
        let mut t =
            Target { raw: &raw, white: &white, linearity: None, full_scale: fs, cfg: &cfg, v: &mut v, fl: &mut fl };
        let mut c = LineCorrection::<1, 3>::new();
        c.frame(FrameRead::Dark, &mut t);
        c.frame(FrameRead::Long(0), &mut t);
        assert_eq!((c.done, c.pending), ([[true, true, true]], 0));
        assert_eq!((v, fl), (want_v, want_fl));
    }
}
