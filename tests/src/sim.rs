//! The host simulation of the firmware (see the crate docs).
use brdf_meter::acquire::AcqConfig;
use brdf_meter::app::{self, LineBuf, Shared};
use brdf_meter::estimate::ZoneMatrix;
use brdf_meter::hw::MappedFlash;
use brdf_meter::platform::host_sim::{Pipe, SimFlash, SimFrames, SimLeds, SimReject, SimSensor, pipe, sim_optics};
use brdf_meter::shape;
use embassy_executor::raw::{Executor, TaskStorage};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex as Cs;
use embassy_sync::zerocopy_channel::Channel;
use embassy_time::{Duration, MockDriver};
use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Mutex, MutexGuard};

/// Angle bins of the simulated build (the QEMU build's shape).
pub const N: usize = shape::BINS;
/// LEDs.
pub const M: usize = shape::LEDS;
/// Pixels.
pub const P: usize = shape::qemu::PIXELS;
/// Frames per line (dark + LEDs).
pub const F: usize = shape::FRAMES_PER_LINE;
/// Calibration slot length.
pub const SLOT_LEN: u32 = shape::qemu::SLOT_LEN;
/// Inspection recipe slot length.
pub const RECIPE_SLOT_LEN: u32 = shape::qemu::RECIPE_SLOT_LEN;
/// Sensor full scale (the QEMU build's, the board's 12-bit converter).
pub const FULL_SCALE: u16 = shape::qemu::FULL_SCALE;
/// Acquisition settings (the QEMU build's, with its shorter exposures).
pub const ACQ: AcqConfig = brdf_meter::platform::timing::QEMU_ACQUISITION;

/// The simulated device's shared state type, on calibration flash `F` (the
/// NOR fake itself, or a window of a simulated chip shared with an updater).
pub type Dev<F = SimFlash> = Shared<F, N, M, P>;

/// The pender of every simulated executor: its context is the executor's
/// own "work pending" flag.
#[unsafe(export_name = "__pender")]
fn pender(context: *mut ()) {
    // SAFETY: every executor here is created with a leaked AtomicBool as context.
    let flag = unsafe { &*(context as *const AtomicBool) };
    flag.store(true, Ordering::SeqCst);
}

/// Mock time is process-wide: one simulation runs at a time.
static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());

/// A simulated instrument (its calibration store on flash `Fl`).
pub struct SimDevice<Fl: 'static = SimFlash> {
    exec: &'static Executor,
    pending: &'static AtomicBool,
    host: Pipe,
    inbox: VecDeque<u8>,
    /// Scene input and LED log.
    pub scene: SimFrames<P, F>,
    /// The application's shared state.
    pub shared: &'static Dev<Fl>,
    /// The flash (shares memory with the device's: the whole simulated chip
    /// when the store has a window of it).
    pub flash: SimFlash,
    /// Simulated time a `recv` waits before reporting nothing, in 100 us
    /// steps ([`RECV_STEPS`] unless a test shortens it).
    pub recv_steps: usize,
    /// The inspection recipe slots (survive a reboot with [`SimFlash::reboot`]).
    pub recipe_flash: SimFlash,
    /// The reject output's record.
    pub reject: SimReject,
    _lock: MutexGuard<'static, ()>,
}

fn leak<T>(x: T) -> &'static mut T {
    Box::leak(Box::new(x))
}

fn spawn<Fut: core::future::Future<Output = ()> + 'static>(exec: &'static Executor, fut: Fut) {
    let storage: &'static TaskStorage<Fut> = leak(TaskStorage::new());
    let token = storage.spawn(|| fut).expect("fresh task storage");
    exec.spawner().spawn(token);
}

impl SimDevice {
    /// Boots a device on `flash` with room for `ram_zones` matrices in RAM
    /// (more zones are read in place from flash).
    pub fn boot(flash: SimFlash, ram_zones: usize) -> Self {
        SimDevice::boot_on(flash.clone(), flash, ram_zones, |_| {})
    }

    /// Boots a device on calibration flash `flash` and recipe flash `recipes`.
    pub fn boot_with_recipes(flash: SimFlash, recipes: SimFlash, ram_zones: usize) -> Self {
        SimDevice::boot_full(flash.clone(), flash, recipes, ram_zones, |_| {})
    }
}

impl<Fl: MappedFlash + 'static> SimDevice<Fl> {
    /// Boots a device whose calibration store is on `store` (a part of the
    /// simulated `chip`), with room for `ram_zones` matrices in RAM;
    /// `setup` completes the application before its tasks start (hands it
    /// an updater, sets the version the running image reports).
    pub fn boot_on(store: Fl, chip: SimFlash, ram_zones: usize, setup: impl FnOnce(&mut Dev<Fl>)) -> Self {
        Self::boot_full(store, chip, SimFlash::new(2 * RECIPE_SLOT_LEN as usize), ram_zones, setup)
    }

    /// [`Self::boot_on`] with the recipe slots on `recipes`.
    pub fn boot_full(
        store: Fl,
        chip: SimFlash,
        recipes: SimFlash,
        ram_zones: usize,
        setup: impl FnOnce(&mut Dev<Fl>),
    ) -> Self {
        let lock = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
        MockDriver::get().reset();
        let ram: &'static mut [ZoneMatrix<N, M>] = Box::leak(vec![ZoneMatrix::zeros(); ram_zones].into_boxed_slice());
        let (host, dev_end) = pipe();
        let (leds, sensor, scene): (SimLeds<P, F>, SimSensor<P, F>, SimFrames<P, F>) =
            sim_optics(FULL_SCALE, ACQ, host.frames_counter());
        // Booted in place, as the firmware boots.
        let shared =
            Shared::init_in_place(leak(core::mem::MaybeUninit::uninit()), store, SLOT_LEN, ram, ACQ, FULL_SCALE, true);
        setup(shared);
        let shared: &'static Dev<Fl> = shared;
        shared.set_recipes(leak(shared.open_recipes(recipes.clone(), RECIPE_SLOT_LEN)));
        let reject = SimReject::default();
        let reject_out = reject.clone();
        let pending: &'static AtomicBool = leak(AtomicBool::new(false));
        let exec: &'static Executor = leak(Executor::new(pending as *const AtomicBool as *mut ()));
        let bufs: &'static mut [LineBuf<M, P>; 2] = leak([LineBuf::new(), LineBuf::new()]);
        let chan: &'static mut Channel<'static, Cs, LineBuf<M, P>> = leak(Channel::new(bufs));
        let (tx_lines, rx_lines) = chan.split();
        let scene_in = scene.clone();
        spawn(exec, async move { app::transport(shared, dev_end.clone(), dev_end, scene_in).await });
        spawn(exec, async move { app::acquisition(shared, leds, sensor, tx_lines).await });
        spawn(exec, async move { app::estimation(shared, rx_lines).await });
        spawn(exec, async move { app::reject_output(shared, reject_out).await });
        let mut dev = Self {
            exec,
            pending,
            host,
            inbox: VecDeque::new(),
            scene,
            shared,
            flash: chip,
            recv_steps: RECV_STEPS,
            recipe_flash: recipes,
            reject,
            _lock: lock,
        };
        pending.store(true, Ordering::SeqCst);
        dev.run_until_idle();
        dev
    }

    /// Polls the executor until no task is ready.
    pub fn run_until_idle(&mut self) {
        while self.pending.swap(false, Ordering::SeqCst) {
            // SAFETY: this thread is the executor's only poller, never reentrant.
            unsafe { self.exec.poll() };
        }
        self.inbox.extend(self.host.drain());
    }

    /// Advances simulated time by `us` microseconds, then runs what woke.
    pub fn advance_us(&mut self, us: u64) {
        MockDriver::get().advance(Duration::from_micros(us));
        self.run_until_idle();
    }
}

/// Simulated time a `recv` waits before reporting nothing, in 100 us steps.
pub const RECV_STEPS: usize = 200_000;

impl<Fl: MappedFlash + 'static> host_tools::device::link::Transport for SimDevice<Fl> {
    fn send(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        self.host.send(bytes);
        self.run_until_idle();
        Ok(())
    }

    /// Runs the device, advancing simulated time while it is idle, until it
    /// has sent something (or 20 simulated seconds have passed).
    fn recv(&mut self, buf: &mut [u8], _timeout: std::time::Duration) -> std::io::Result<usize> {
        for _ in 0..self.recv_steps {
            self.run_until_idle();
            if !self.inbox.is_empty() {
                let n = buf.len().min(self.inbox.len());
                for (d, s) in buf.iter_mut().zip(self.inbox.drain(..n)) {
                    *d = s;
                }
                return Ok(n);
            }
            self.advance_us(100);
        }
        Ok(0)
    }
}
