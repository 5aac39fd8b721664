//! Simulated LEDs and line sensor for the host simulation. The sensor serves
//! frames from a [`FrameStore`] (the same one the QEMU firmware uses) and sees
//! which LED is lit through the shared state, as a real sensor sees light.
use crate::acquire::AcqConfig;
use crate::frame_store::FrameStore;
use crate::hw::{FrameInput, FrameLoadError, Leds, LineSensor, SensorError};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

/// Scene lines the host simulation holds.
pub const SIM_LINES: usize = 4;

struct State<const P: usize, const F: usize> {
    scene: FrameStore<P, F, SIM_LINES>,
    lit: Option<u8>,
    /// LED switch log, per `Leds::set`: the LED lit and how many frames the
    /// device had written to the link by then (for tests of the pipeline).
    switches: Vec<(Option<u8>, usize)>,
    frames_out: Arc<AtomicUsize>,
}

/// Shared handle on the simulated optics: give [`SimLeds`], [`SimSensor`] and
/// [`SimFrames`] to the application; all three see one state. `frames_out`
/// counts the frames the device has sent ([`super::Pipe::frames_counter`]).
pub fn sim_optics<const P: usize, const F: usize>(
    full_scale: u16,
    acq: AcqConfig,
    frames_out: Arc<AtomicUsize>,
) -> (SimLeds<P, F>, SimSensor<P, F>, SimFrames<P, F>) {
    let st = Arc::new(Mutex::new(State { scene: FrameStore::new(), lit: None, switches: Vec::new(), frames_out }));
    (SimLeds { st: st.clone() }, SimSensor { st: st.clone(), full_scale, acq }, SimFrames { st })
}

/// Simulated LEDs (F - 1 of them).
pub struct SimLeds<const P: usize, const F: usize> {
    st: Arc<Mutex<State<P, F>>>,
}

/// Simulated line sensor of P pixels.
pub struct SimSensor<const P: usize, const F: usize> {
    st: Arc<Mutex<State<P, F>>>,
    full_scale: u16,
    /// The acquisition's exposures: which level a frame's exposure is.
    acq: AcqConfig,
}

/// The simulation's scene input (and a test's view of the optics).
#[derive(Clone)]
pub struct SimFrames<const P: usize, const F: usize> {
    st: Arc<Mutex<State<P, F>>>,
}

impl<const P: usize, const F: usize> SimFrames<P, F> {
    /// LED switches so far (`None` = all off).
    pub fn switches(&self) -> Vec<Option<u8>> {
        self.st.lock().unwrap().switches.iter().map(|s| s.0).collect()
    }
    /// LED switches so far, each with the number of frames the device had
    /// sent when it happened.
    pub fn switches_timed(&self) -> Vec<(Option<u8>, usize)> {
        self.st.lock().unwrap().switches.clone()
    }
}

impl<const P: usize, const F: usize> Leds for SimLeds<P, F> {
    fn count(&self) -> usize {
        F - 1
    }
    async fn set(&mut self, led: Option<u8>, _intensity: u16) {
        let mut st = self.st.lock().unwrap();
        st.lit = led;
        let sent = st.frames_out.load(Ordering::SeqCst);
        st.switches.push((led, sent));
    }
}

impl<const P: usize, const F: usize> LineSensor for SimSensor<P, F> {
    fn pixels(&self) -> usize {
        P
    }
    fn full_scale(&self) -> u16 {
        self.full_scale
    }
    async fn read_frame(&mut self, exposure_us: u32, out: &mut [u16]) -> Result<(), SensorError> {
        // Integration takes time, in simulated time too.
        embassy_time::Timer::after_micros(exposure_us as u64).await;
        let mut st = self.st.lock().unwrap();
        let lit = st.lit;
        st.scene.read(lit, self.acq.level_of(exposure_us), out)
    }
}

impl<const P: usize, const F: usize> FrameInput for SimFrames<P, F> {
    fn load(&mut self, line: u8, frame: u8, first: u16, px: impl Iterator<Item = u16>) -> Result<(), FrameLoadError> {
        self.st.lock().unwrap().scene.load(line, frame, first, px)
    }
    fn set_lines(&mut self, lines: u8) -> Result<(), FrameLoadError> {
        self.st.lock().unwrap().scene.set_lines(lines)
    }
    fn simulated(&self) -> bool {
        true
    }
}
