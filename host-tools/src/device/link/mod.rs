//! The host's end of the device link: byte transports (a real serial port, the
//! QEMU instrument's TCP serial, or anything implementing [`Transport`], such
//! as the host simulation's in-memory pipe) and the [`Client`] that speaks the
//! wire protocol defined once in `brdf_meter::protocol`.
mod client;
mod firmware;
mod inspect;
pub mod qemu;
mod retrying;
mod serial;
mod stream;
mod tcp;

pub use client::{Client, Frame, LinkError, PointRecord, Reply};
pub use inspect::{InspectRun, PulseEvent, end_of_run_wait, frame_len};
pub use retrying::{LinkStats, ProvisionOutcome, StreamReport};
pub use serial::SerialTransport;
pub use stream::{DecodeError, StreamDecoder, decode_points, decode_with};
pub use tcp::TcpTransport;

use std::time::Duration;

/// A byte link to a device.
pub trait Transport {
    /// Sends all of `bytes`.
    fn send(&mut self, bytes: &[u8]) -> std::io::Result<()>;
    /// Receives at least one byte into `buf`, waiting at most `timeout`;
    /// returns 0 if nothing arrived in time.
    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> std::io::Result<usize>;
}

impl<T: Transport + ?Sized> Transport for Box<T> {
    fn send(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        (**self).send(bytes)
    }
    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> std::io::Result<usize> {
        (**self).recv(buf, timeout)
    }
}

/// Where the device is, as given on the command line.
#[derive(Clone, Debug, clap::Args)]
#[group(required = true, multiple = false)]
pub struct Endpoint {
    /// Serial port of a real instrument (e.g. /dev/ttyACM0).
    #[arg(long, value_name = "PATH")]
    pub port: Option<String>,
    /// TCP serial of the QEMU instrument (e.g. 127.0.0.1:4555, printed by `host-tools qemu`).
    #[arg(long, value_name = "HOST:PORT")]
    pub tcp: Option<String>,
}

impl Endpoint {
    /// Opens the transport.
    pub fn open(&self) -> anyhow::Result<Box<dyn Transport>> {
        use anyhow::Context;
        Ok(match (&self.port, &self.tcp) {
            (Some(p), _) => Box::new(SerialTransport::open(p).with_context(|| format!("opening serial port {p}"))?),
            (_, Some(a)) => Box::new(
                TcpTransport::connect(a)
                    .with_context(|| format!("connecting to {a} (is `host-tools qemu` running?)"))?,
            ),
            _ => anyhow::bail!("give --port PATH or --tcp HOST:PORT"),
        })
    }
}
