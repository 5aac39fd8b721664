//! embassy-time driver on SysTick: QEMU's TIM peripherals are stubs, SysTick
//! is emulated. SysTick interrupts every 100 us and counts; `now()` is that
//! count in embassy-time ticks (1 MHz), so timers have 100 us resolution,
//! plenty for LED settling and exposure times in a simulation.
use core::cell::{Cell, RefCell};
use core::task::Waker;
use cortex_m::peripheral::syst::SystClkSource;
use cortex_m_rt::exception;
use embassy_sync::blocking_mutex::CriticalSectionMutex as Mutex;
use embassy_time_driver::Driver;
use embassy_time_queue_utils::Queue;

/// Core clock of the machine at reset: MSI at 4 MHz (QEMU models the RCC and
/// this firmware does not reprogram it).
pub const CORE_HZ: u32 = 4_000_000;
/// SysTick rate.
const TICK_HZ: u32 = 10_000;
const US_PER_TICK: u64 = 1_000_000 / TICK_HZ as u64;

struct SysTickDriver {
    ticks: Mutex<Cell<u64>>,
    queue: Mutex<RefCell<Queue>>,
}

embassy_time_driver::time_driver_impl!(static DRIVER: SysTickDriver = SysTickDriver {
    ticks: Mutex::new(Cell::new(0)),
    queue: Mutex::new(RefCell::new(Queue::new())),
});

impl Driver for SysTickDriver {
    fn now(&self) -> u64 {
        self.ticks.lock(|t| t.get()) * US_PER_TICK
    }
    fn schedule_wake(&self, at: u64, waker: &Waker) {
        let now = self.now();
        self.queue.lock(|q| {
            let mut q = q.borrow_mut();
            q.schedule_wake(at, waker);
            // Wakes what is already due; the rest waits for a tick.
            q.next_expiration(now);
        });
    }
}

/// Starts SysTick.
pub fn init(mut syst: cortex_m::peripheral::SYST) {
    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload(CORE_HZ / TICK_HZ - 1);
    syst.clear_current();
    syst.enable_interrupt();
    syst.enable_counter();
}

#[exception]
fn SysTick() {
    let now = DRIVER.ticks.lock(|t| {
        t.set(t.get() + 1);
        t.get()
    }) * US_PER_TICK;
    DRIVER.queue.lock(|q| q.borrow_mut().next_expiration(now));
}
