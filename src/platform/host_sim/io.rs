//! An in-memory byte link: the device end implements `embedded_io_async`
//! Read/Write (what the application's transport needs), the host end is plain
//! synchronous push/drain for the test driving the simulation.
use core::task::{Poll, Waker};
use std::collections::VecDeque;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

#[derive(Default)]
struct Queue {
    bytes: VecDeque<u8>,
    reader: Option<Waker>,
}

/// The host's end of the link.
#[derive(Clone)]
pub struct Pipe {
    to_device: Arc<Mutex<Queue>>,
    from_device: Arc<Mutex<Queue>>,
    frames: Arc<AtomicUsize>,
}

/// The device's end of the link (clone it to give the reader and the writer
/// their own handle).
#[derive(Clone)]
pub struct PipeEnd {
    rx: Arc<Mutex<Queue>>,
    tx: Arc<Mutex<Queue>>,
    frames: Arc<AtomicUsize>,
}

/// A connected pair.
pub fn pipe() -> (Pipe, PipeEnd) {
    let a = Arc::new(Mutex::new(Queue::default()));
    let b = Arc::new(Mutex::new(Queue::default()));
    let f = Arc::new(AtomicUsize::new(0));
    (Pipe { to_device: a.clone(), from_device: b.clone(), frames: f.clone() }, PipeEnd { rx: a, tx: b, frames: f })
}

impl Pipe {
    /// Sends bytes to the device (wakes its reader).
    pub fn send(&self, bytes: &[u8]) {
        let mut q = self.to_device.lock().unwrap();
        q.bytes.extend(bytes.iter().copied());
        if let Some(w) = q.reader.take() {
            w.wake();
        }
    }
    /// Counts the frames (0x00 delimiters) the device has written.
    pub fn frames_counter(&self) -> Arc<AtomicUsize> {
        self.frames.clone()
    }
    /// Takes everything the device wrote so far.
    pub fn drain(&self) -> Vec<u8> {
        self.from_device.lock().unwrap().bytes.drain(..).collect()
    }
}

impl embedded_io_async::ErrorType for PipeEnd {
    type Error = core::convert::Infallible;
}

impl embedded_io_async::Read for PipeEnd {
    async fn read(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error> {
        core::future::poll_fn(|cx| {
            let mut q = self.rx.lock().unwrap();
            if q.bytes.is_empty() {
                q.reader = Some(cx.waker().clone());
                return Poll::Pending;
            }
            let n = buf.len().min(q.bytes.len());
            for (d, s) in buf.iter_mut().zip(q.bytes.drain(..n)) {
                *d = s;
            }
            Poll::Ready(Ok(n))
        })
        .await
    }
}

impl embedded_io_async::Write for PipeEnd {
    async fn write(&mut self, buf: &[u8]) -> Result<usize, Self::Error> {
        self.tx.lock().unwrap().bytes.extend(buf.iter().copied());
        self.frames.fetch_add(buf.iter().filter(|b| **b == 0).count(), Ordering::SeqCst);
        Ok(buf.len())
    }
    async fn flush(&mut self) -> Result<(), Self::Error> {
        Ok(())
    }
}
