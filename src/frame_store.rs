//! The frame store of a simulated line sensor, shared by the QEMU firmware and
//! the host simulation so both serve frames by the same rule.
//!
//! The host loads raw frames (dark + one per LED, P pixels of u16) for up to
//! `L` lines with the simulation-only protocol messages. A read returns
//! the frame of the LED that is lit (the sensor sees the LEDs, as a real one
//! would); each dark-frame read starts the next loaded line, cycling through
//! the loaded lines, so line k of a measurement sees loaded line k mod lines.
use crate::hw::{FrameLoadError, SensorError};

/// Frames of `L` lines, `F` frames (dark + LEDs) of `P` pixels each.
pub struct FrameStore<const P: usize, const F: usize, const L: usize> {
    frames: [[[u16; P]; F]; L],
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
        Self { frames: [[[0; P]; F]; L], lines: 0, current: 0, started: false }
    }

    /// Stores pixel values of one frame part.
    pub fn load(
        &mut self,
        line: u8,
        frame: u8,
        first_pixel: u16,
        pixels: impl Iterator<Item = u16>,
    ) -> Result<(), FrameLoadError> {
        let (line, frame, first) = (line as usize, frame as usize, first_pixel as usize);
        if line >= L || frame >= F || first >= P {
            return Err(FrameLoadError::OutOfRange);
        }
        let dst = &mut self.frames[line][frame][first..];
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

    /// The frame the sensor sees with LED `lit` on (`None`: dark).
    pub fn read(&mut self, lit: Option<u8>, out: &mut [u16]) -> Result<(), SensorError> {
        if out.len() != P {
            return Err(SensorError::BadLength);
        }
        if self.lines == 0 {
            return Err(SensorError::NoData);
        }
        let frame = match lit {
            None => {
                if self.started {
                    self.current = (self.current + 1) % self.lines as usize;
                }
                self.started = true;
                0
            }
            Some(k) => k as usize + 1,
        };
        let frame = self.frames[self.current].get(frame).ok_or(SensorError::NoData)?;
        out.copy_from_slice(frame);
        Ok(())
    }
}
