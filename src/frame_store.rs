//! The frame store of a simulated line sensor, shared by the QEMU firmware and
//! the host simulation so both serve frames by the same rule.
//!
//! The host loads raw frames (dark + one per LED, P pixels of u16) for up to
//! `L` lines with the simulation-only protocol messages, at the long
//! exposure and at each of the acquisition's shorter exposures (frame
//! `level F + f`, level 0 the long exposure, `crate::acquire`). A read
//! returns the frame of the LED that is lit at the exposure integrated (the
//! sensor sees the LEDs, as a real one would); each long dark-frame read
//! starts the next loaded line, cycling through the loaded lines, so line k
//! of a measurement sees loaded line k mod lines.
use crate::hw::{FrameLoadError, SensorError};

/// Exposure levels a frame store holds: the long one and the shorter ones.
pub const LEVELS: usize = 1 + crate::acquire::MAX_SHORT_EXPOSURES;

/// Frames of `L` lines, [`LEVELS`] exposures of `F` frames (dark + LEDs) of
/// `P` pixels each.
pub struct FrameStore<const P: usize, const F: usize, const L: usize> {
    frames: [[[[u16; P]; F]; LEVELS]; L],
    /// Per line, which exposure levels have frames loaded.
    loaded: [[bool; LEVELS]; L],
    lines: u8,
    current: usize,
    started: bool,
}

impl<const P: usize, const F: usize, const L: usize> Default for FrameStore<P, F, L> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const P: usize, const F: usize, const L: usize> FrameStore<P, F, L> {
    /// An empty store: reads fail with [`SensorError::NoData`] until
    /// [`Self::set_lines`].
    pub const fn new() -> Self {
        Self { frames: [[[[0; P]; F]; LEVELS]; L], loaded: [[false; LEVELS]; L], lines: 0, current: 0, started: false }
    }

    /// Stores pixel values of one frame part: frame `level F + f` of the
    /// line (f = 0 dark, 1 + LED). Load a line's frames in order: its long
    /// dark frame (frame 0) first, which forgets the line's shorter
    /// exposures until they are loaded again.
    pub fn load(
        &mut self,
        line: u8,
        frame: u8,
        first_pixel: u16,
        pixels: impl Iterator<Item = u16>,
    ) -> Result<(), FrameLoadError> {
        let (line, frame, first) = (line as usize, frame as usize, first_pixel as usize);
        if line >= L || frame >= LEVELS * F || first >= P {
            return Err(FrameLoadError::OutOfRange);
        }
        // Loading a line's long dark frame starts the line afresh: shorter
        // exposures count as loaded only when loaded after it.
        if frame == 0 && first == 0 {
            self.loaded[line] = [false; LEVELS];
        }
        self.loaded[line][frame / F] = true;
        let dst = &mut self.frames[line][frame / F][frame % F][first..];
        let mut n = 0;
        for (d, v) in dst.iter_mut().zip(pixels) {
            *d = v;
            n += 1;
        }
        let _ = n;
        Ok(())
    }

    /// Sets the number of loaded lines in use (1..=L) and restarts at line 0.
    pub fn set_lines(&mut self, lines: u8) -> Result<(), FrameLoadError> {
        if lines == 0 || lines as usize > L {
            return Err(FrameLoadError::OutOfRange);
        }
        self.lines = lines;
        self.current = 0;
        self.started = false;
        Ok(())
    }

    /// The frame the sensor sees with LED `lit` on (`None`: dark) at
    /// exposure `level` (0: the long exposure).
    pub fn read(&mut self, lit: Option<u8>, level: usize, out: &mut [u16]) -> Result<(), SensorError> {
        if out.len() != P {
            return Err(SensorError::BadLength);
        }
        if self.lines == 0 {
            return Err(SensorError::NoData);
        }
        let frame = match lit {
            None if level > 0 => 0,
            None => {
                if self.started {
                    self.current = (self.current + 1) % self.lines as usize;
                }
                self.started = true;
                0
            }
            Some(k) => k as usize + 1,
        };
        // A shorter exposure the host loaded no frames for: none to give.
        if level > 0 && !self.loaded[self.current].get(level).copied().unwrap_or(false) {
            return Err(SensorError::NoData);
        }
        let frame = self.frames[self.current].get(level).and_then(|l| l.get(frame)).ok_or(SensorError::NoData)?;
        out.copy_from_slice(frame);
        Ok(())
    }
}
