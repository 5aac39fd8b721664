//! The instrument's application, platform-agnostic: the board firmware, the
//! QEMU firmware and the host simulation run exactly this code and differ only
//! in the hardware they hand it and the executor that runs it.
//!
//! Three tasks, joined by embassy-sync channels:
//!
//! ```text
//!  transport ──(start/stop)──> acquisition ──[line buffer x2]──> estimation
//!      ^  requests, replies          LEDs + sensor, correction      W v per point
//!      └──────────────(encoded frames: replies, points)─────────────┘
//! ```
//!
//! The two line buffers are a zero-copy channel: acquisition fills one while
//! estimation works on (and the transport sends) the other, so line k+1 is
//! acquired while line k is estimated and sent.
//!
//! Embassy tasks cannot be generic, so each platform writes three one-line
//! `#[embassy_executor::task]` wrappers around [`acquisition`], [`estimation`]
//! and [`transport`] with its concrete types (see `src/bin/qemu-fw.rs`).
mod handler;
mod inspect;
mod self_test;
mod tasks;
mod update;
#[cfg(feature = "usb-dfu")]
pub mod usb_dfu;

pub use inspect::{InspectJob, RecipePort, RecipeSlots, reject_output};
pub use tasks::{acquisition, estimation, reboot, transport};

use crate::acquire::{AcqConfig, RawLine};
use crate::estimate::{Calibration, ZoneMatrix};
use crate::hw::MappedFlash;
use crate::protocol::{DeviceStatus, MAX_FRAME};
use crate::store::Store;
use core::cell::RefCell;
use core::sync::atomic::AtomicBool;
use embassy_sync::blocking_mutex::Mutex as BlockingMutex;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex as Cs;
use embassy_sync::channel::Channel;
use embassy_sync::signal::Signal;
use nalgebra::SVector;

/// An encoded frame on its way to the host.
pub type OutFrame = heapless::Vec<u8, MAX_FRAME>;

/// Firmware version reported by `Info` and `FirmwareInfo`: bump it for
/// every firmware that ships.
pub const FIRMWARE_VERSION: [u8; 3] = [0, 1, 0];

/// The same version as a named symbol of the firmware's ELF, so that
/// `host-tools sign-firmware` signs an image with the version the image
/// itself reports (it reads this symbol's bytes from the ELF); the firmware
/// reads its version from here, which also keeps the symbol in the image.
#[unsafe(no_mangle)]
pub static BRDF_FIRMWARE_VERSION: [u8; 3] = FIRMWARE_VERSION;

/// The version this build reports: [`BRDF_FIRMWARE_VERSION`], read so the
/// linker keeps it.
fn built_version() -> [u8; 3] {
    // SAFETY: a valid, immutable static; volatile only so the read (and so
    // the symbol) is not optimised away.
    unsafe { core::ptr::read_volatile(&raw const BRDF_FIRMWARE_VERSION) }
}

/// A measurement to run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Job {
    /// Sequence number of the `Measure` request (echoed in every frame).
    pub seq: u32,
    /// Lines to measure, 0 for continuous.
    pub lines: u32,
    /// What the stream carries (bins already checked against n).
    pub format: crate::protocol::StreamFormat,
    /// An inspection (verdicts per line) rather than a measurement.
    pub inspect: Option<InspectJob>,
}

/// What travels in a line buffer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LineState {
    /// Nothing yet.
    Empty,
    /// A corrected line, number `line` of `job`.
    Line {
        /// Job.
        job: Job,
        /// Line number within the job.
        line: u32,
    },
    /// The job is over after `lines` lines (error or done); estimation sends
    /// the error, if any, then `MeasureDone`, after the lines before it.
    End {
        /// Job.
        job: Job,
        /// Lines measured.
        lines: u32,
        /// Why it ended early.
        error: Option<crate::protocol::DeviceError>,
    },
}

/// One line buffer: raw frames, corrected readings and flags per pixel.
pub struct LineBuf<const M: usize, const P: usize> {
    /// What this buffer holds.
    pub state: LineState,
    /// Raw frames.
    pub raw: RawLine<M, P>,
    /// Corrected readings per pixel.
    pub v: [SVector<f32, M>; P],
    /// Flags per pixel.
    pub flags: [u8; P],
    /// An inspection's first part of each point's statistics, worked out
    /// while the line's last LED frame integrated.
    pub early: crate::inspect::decide::UnscaledLine<P>,
}

impl<const M: usize, const P: usize> LineBuf<M, P> {
    /// An empty buffer.
    pub const fn new() -> Self {
        Self {
            state: LineState::Empty,
            raw: RawLine::new(),
            v: [SVector::from_array_storage(nalgebra::ArrayStorage([[0.0; M]; 1])); P],
            flags: [0; P],
            early: crate::inspect::decide::UnscaledLine::new(),
        }
    }
}

impl<const M: usize, const P: usize> LineBuf<M, P> {
    /// Writes `K` empty line buffers into `slot` in place and returns them.
    /// The firmware's two (29 KB on the board) are too large to build on
    /// the stack and move into their static, as `StaticCell::init` would.
    pub fn init_in_place<const K: usize>(slot: &mut core::mem::MaybeUninit<[Self; K]>) -> &mut [Self; K] {
        let p = slot.as_mut_ptr();
        // SAFETY: `p` is valid for writes of one `[Self; K]`. Every field of
        // an empty buffer but `state` is integers, floats and bools, for
        // which zero bytes are the valid values 0, 0.0 and false (what
        // `new` gives); each `state`, whose zero bytes need not be a valid
        // `LineState`, is written whole before the reference is made.
        unsafe {
            core::ptr::write_bytes(p, 0, 1);
            for k in 0..K {
                core::ptr::addr_of_mut!((*p)[k].state).write(LineState::Empty);
            }
            &mut *p
        }
    }
}

impl<const M: usize, const P: usize> Default for LineBuf<M, P> {
    fn default() -> Self {
        Self::new()
    }
}

/// The platform's firmware updater, as the application holds it.
pub type FirmwarePort = &'static mut (dyn crate::firmware::update::FirmwareSlot + Send);

/// State the request handler and the tasks share.
pub struct Core<F, const N: usize, const M: usize, const P: usize> {
    /// Calibration store.
    pub store: Store<F>,
    /// Active calibration.
    pub cal: Calibration<N, M, P>,
    /// Counters and flags.
    pub status: DeviceStatus,
    /// The firmware updater, on a platform with an update partition.
    pub firmware: Option<FirmwarePort>,
    /// The self-test that confirms a trial image (see `self_test`).
    pub self_test: crate::protocol::SelfTest,
    /// Why the last firmware update request (link or USB DFU) was refused,
    /// until an update is committed: USB DFU can only say "verify failed",
    /// `FirmwareInfo` says what.
    pub update_refused: Option<crate::protocol::DeviceError>,
    /// The inspection recipe store, on a platform with recipe slots.
    pub recipes: Option<RecipePort>,
    /// The inspection's state across lines and its counters.
    pub inspector: crate::inspect::Inspector<P>,
    /// The reject pulses waiting for their line.
    pub reject_plan: crate::inspect::reject::Planner,
    /// Reject pulses handed to the reject output and not yet reported on the
    /// link (a merged pulse reports every one it took in): an inspection's
    /// `MeasureDone` waits for them, so the host has every pulse of its run
    /// when it sees the run end.
    pub pulses_under_way: u32,
    /// An inspection is past its last line and waits for those pulses.
    pub awaiting_pulses: bool,
    /// Whether the running job is an inspection.
    pub inspecting: bool,
    /// The recipe of the running inspection, parsed once when it started
    /// (the store never writes the active slot, and neither the recipe nor
    /// the calibration can change while a job runs).
    pub recipe_view: Option<crate::inspect::RecipeView<'static>>,
    /// Points of inspected lines whose first part of the decision was
    /// worked out while their line's last frame integrated (a diagnostic:
    /// the rest are decided whole after the last frame).
    pub early_points: u32,
}

impl<F: MappedFlash, const N: usize, const M: usize, const P: usize> Core<F, N, M, P> {
    /// The core on `store` with no calibration loaded yet.
    fn booting(store: Store<F>, ram: &'static mut [ZoneMatrix<N, M>]) -> Self {
        Self {
            store,
            cal: Calibration::new(ram),
            status: DeviceStatus::default(),
            firmware: None,
            // The store was opened and both slots read: the self-test's first part.
            self_test: crate::protocol::SelfTest { store: true, ..Default::default() },
            update_refused: None,
            recipes: None,
            inspector: crate::inspect::Inspector::new(),
            reject_plan: crate::inspect::reject::Planner::new(),
            pulses_under_way: 0,
            awaiting_pulses: false,
            inspecting: false,
            recipe_view: None,
            early_points: 0,
        }
    }
}

/// Everything the three tasks share; the platform puts one in a `static`.
pub struct Shared<F, const N: usize, const M: usize, const P: usize> {
    /// Store, calibration, status. A blocking mutex: every use is short and
    /// never awaits while holding it.
    pub core: BlockingMutex<Cs, RefCell<Core<F, N, M, P>>>,
    /// Transport -> acquisition: start a job.
    pub start: Signal<Cs, Job>,
    /// Transport -> acquisition: stop after the line in progress.
    pub stop: AtomicBool,
    /// Estimation and transport -> transport writer: encoded frames.
    pub out: Channel<Cs, OutFrame, 4>,
    /// Acquisition settings.
    pub acq: AcqConfig,
    /// The sensor's full scale (for saturation flags).
    pub full_scale: u16,
    /// Whether the sensor is simulated (reported by `Info`).
    pub simulated: bool,
    /// Transport -> platform: reset the device (a `Reboot` request was
    /// answered; the platform resets once the reply has left).
    pub reboot: Signal<Cs, ()>,
    /// The machine this build is for (firmware images must match it).
    pub target: crate::firmware::image::Target,
    /// The running firmware's version (`Info`, `FirmwareInfo`).
    pub version: [u8; 3],
    /// Estimation -> reject output: pulses to drive (with the job's sequence number).
    pub reject: Channel<Cs, (u32, crate::inspect::reject::Pulse), 4>,
    /// Reject output -> estimation: a pulse has been reported and taken off
    /// the count under way (an inspection waiting for its last pulses looks
    /// at the count again).
    pub pulse_reported: Signal<Cs, ()>,
}

impl<F: MappedFlash, const N: usize, const M: usize, const P: usize> Shared<F, N, M, P> {
    /// Boots into `slot`, in place: opens the store on `flash` (two slots
    /// of `slot_len` bytes), takes the newest valid blob made for this
    /// build, and loads it (matrices to `ram` when they fit, else in
    /// place). In place because the application (10 KB on the board) built
    /// on the stack and moved into its static, as `StaticCell::init` would,
    /// would take that much stack for good, in the frame of a `main` that
    /// never returns. The host simulation boots through here too.
    pub fn init_in_place<'a>(
        slot: &'a mut core::mem::MaybeUninit<Self>,
        flash: F,
        slot_len: u32,
        ram: &'static mut [ZoneMatrix<N, M>],
        acq: AcqConfig,
        full_scale: u16,
        simulated: bool,
    ) -> &'a mut Self {
        let store = Self::open_store(flash, slot_len);
        let p = slot.as_mut_ptr();
        // SAFETY: `p` is valid for writes of one `Self`, and every field is
        // written before the reference is made.
        let shared = unsafe {
            use core::ptr::addr_of_mut;
            addr_of_mut!((*p).core).write(BlockingMutex::new(RefCell::new(Core::booting(store, ram))));
            addr_of_mut!((*p).start).write(Signal::new());
            addr_of_mut!((*p).stop).write(AtomicBool::new(false));
            addr_of_mut!((*p).out).write(Channel::new());
            addr_of_mut!((*p).acq).write(acq);
            addr_of_mut!((*p).full_scale).write(full_scale);
            addr_of_mut!((*p).simulated).write(simulated);
            addr_of_mut!((*p).reboot).write(Signal::new());
            addr_of_mut!((*p).reject).write(Channel::new());
            addr_of_mut!((*p).pulse_reported).write(Signal::new());
            addr_of_mut!((*p).version).write(built_version());
            addr_of_mut!((*p).target).write(Self::target_of(simulated));
            slot.assume_init_mut()
        };
        // Every field above: a field added to `Shared` fails to compile here
        // until it is written too.
        let Self {
            core: _,
            start: _,
            stop: _,
            out: _,
            acq: _,
            full_scale: _,
            simulated: _,
            reboot: _,
            reject: _,
            pulse_reported: _,
            version: _,
            target: _,
        } = shared;
        shared.load_active();
        shared
    }

    fn open_store(flash: F, slot_len: u32) -> Store<F> {
        Store::open(flash, slot_len, crate::signed::TRUSTED_KEYS, |v| Calibration::<N, M, P>::check(v).is_ok())
    }

    /// The machine this build is for: QEMU's for a simulated sensor.
    fn target_of(simulated: bool) -> crate::firmware::image::Target {
        if simulated { crate::firmware::image::Target::Qemu } else { crate::firmware::image::Target::Board }
    }

    /// Loads the store's newest valid blob, as booting does.
    fn load_active(&self) {
        self.core.lock(|c| {
            let c = &mut *c.borrow_mut();
            if let Some((info, view)) = c.store.active_blob() {
                // Checked by `open`'s filter; a failure here would leave no
                // calibration, which Measure reports as NoCalibration.
                let _ = c.cal.load(&view, info);
            }
            c.status.calibration = c.cal.active().map(|a| a.info);
        });
    }

    /// Hands the application the platform's firmware updater: it then
    /// takes updates over the link and confirms a trial boot after its
    /// self-test.
    pub fn set_firmware(&self, port: FirmwarePort) {
        self.core.lock(|c| c.borrow_mut().firmware = Some(port));
    }

    /// A copy of the status.
    pub fn status(&self) -> DeviceStatus {
        self.core.lock(|c| c.borrow().status)
    }

    /// Whether lines are to complete: a job runs and is not an inspection
    /// past its last line, waiting for its reject pulses (which a delay in
    /// time may hold for seconds). What the watchdog's stall rule watches.
    pub fn measuring_lines(&self) -> bool {
        self.core.lock(|c| {
            let c = c.borrow();
            c.status.measuring && !c.awaiting_pulses
        })
    }
}
