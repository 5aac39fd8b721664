//! A real instrument on a serial port (USB CDC-ACM shows up as /dev/ttyACM*).
use super::Transport;
use std::io::{Read, Write};
use std::time::Duration;

/// A serial-port transport (the `serialport` crate, built without libudev).
pub struct SerialTransport {
    port: Box<dyn serialport::SerialPort>,
}

impl SerialTransport {
    /// Opens `path` at 115200 8N1 (ignored by CDC-ACM, used by real UARTs).
    pub fn open(path: &str) -> Result<Self, serialport::Error> {
        let port = serialport::new(path, 115_200).timeout(Duration::from_millis(100)).open()?;
        Ok(Self { port })
    }
}

impl Transport for SerialTransport {
    fn send(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        self.port.write_all(bytes)?;
        self.port.flush()
    }
    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> std::io::Result<usize> {
        self.port.set_timeout(timeout).map_err(std::io::Error::other)?;
        match self.port.read(buf) {
            Ok(n) => Ok(n),
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => Ok(0),
            Err(e) => Err(e),
        }
    }
}
