//! The host simulation's reject output: every level it is driven to, with
//! the simulated time, for the tests to read (the board drives a GPIO; QEMU
//! cannot show one, see `crate::app::reject_output`).
use crate::hw::RejectOutput;
use std::sync::{Arc, Mutex};

/// A reject output that records its edges (clones share the record).
#[derive(Clone, Default)]
pub struct SimReject {
    edges: Arc<Mutex<Vec<(u64, bool)>>>,
}

impl SimReject {
    /// Every change of level so far: (us of simulated time, level).
    pub fn edges(&self) -> Vec<(u64, bool)> {
        self.edges.lock().unwrap_or_else(|e| e.into_inner()).clone()
    }
}

impl RejectOutput for SimReject {
    fn set(&mut self, on: bool) {
        let mut e = self.edges.lock().unwrap_or_else(|e| e.into_inner());
        if e.last().map(|x| x.1) != Some(on) {
            e.push((embassy_time::Instant::now().as_micros(), on));
        }
    }
}
