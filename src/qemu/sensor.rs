//! A simulated line sensor: frames come from a scene the host loads over the
//! link (simulation-only protocol messages) into a [`SceneStore`]; the frame
//! served is the one of the LED the GPIO pins light, as a real sensor would see.
use brdf_meter::hw::{LineSensor, SceneError, SceneInput, SensorError};
use brdf_meter::scene::SceneStore;
use core::cell::RefCell;
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex as Cs;

/// The scene, shared by the sensor and the transport's scene input.
pub struct Scene<const P: usize, const F: usize, const L: usize>(Mutex<Cs, RefCell<SceneStore<P, F, L>>>);

impl<const P: usize, const F: usize, const L: usize> Scene<P, F, L> {
    /// Empty.
    pub const fn new() -> Self {
        Self(Mutex::new(RefCell::new(SceneStore::new())))
    }
}

/// The simulated sensor.
pub struct SimSensor<const P: usize, const F: usize, const L: usize> {
    /// Scene.
    pub scene: &'static Scene<P, F, L>,
    /// Full scale reported.
    pub full_scale: u16,
    /// Which LED is lit (read from the pins).
    pub lit: fn() -> Option<u8>,
}

impl<const P: usize, const F: usize, const L: usize> LineSensor for SimSensor<P, F, L> {
    fn pixels(&self) -> usize {
        P
    }
    fn full_scale(&self) -> u16 {
        self.full_scale
    }
    async fn read_frame(&mut self, exposure_us: u32, out: &mut [u16]) -> Result<(), SensorError> {
        embassy_time::Timer::after_micros(exposure_us as u64).await;
        let lit = (self.lit)();
        self.scene.0.lock(|s| s.borrow_mut().read(lit, out))
    }
}

/// The transport's handle on the scene.
pub struct SceneIn<const P: usize, const F: usize, const L: usize>(pub &'static Scene<P, F, L>);

impl<const P: usize, const F: usize, const L: usize> SceneInput for SceneIn<P, F, L> {
    fn load(&mut self, line: u8, frame: u8, first: u16, px: impl Iterator<Item = u16>) -> Result<(), SceneError> {
        self.0.0.lock(|s| s.borrow_mut().load(line, frame, first, px))
    }
    fn set_lines(&mut self, lines: u8) -> Result<(), SceneError> {
        self.0.0.lock(|s| s.borrow_mut().set_lines(lines))
    }
    fn simulated(&self) -> bool {
        true
    }
}
