//! The link: USB full-speed bulk IN, 64-byte packets, at most 19 per 1 ms
//! frame (USB 2.0, 5.8.4: 19 x 64-byte transactions fit a full-speed frame).
//!
//! The board writes each protocol frame with `write_all` and `flush`
//! (`platform::board::usb`): 64-byte packets, the last one short, and a
//! zero-length packet after a frame whose length is a multiple of 64. So a
//! frame of L bytes costs `ceil(L / 64)` packets (+ 1 when 64 divides L),
//! and a short packet takes a transaction slot as a full one does.
//!
//! Practical rate: the theoretical 19 packets per frame needs the device to
//! have the next packet ready at every IN token; embassy-usb queues one
//! packet at a time (`write_packet` waits for its completion, then the task
//! is woken to queue the next), so some IN tokens are NAKed and retried
//! later in the frame. With no board to measure it, the practical figure
//! assumed here is [`PRACTICAL_PACKETS_PER_MS`] (about half the theory; a
//! one-packet-at-a-time CDC-ACM stack on another 64-byte-endpoint chip was
//! measured at 330 kB/s, about 5 packets per frame, so this is not a floor).
//! The report gives the link time at both rates.
use serde::Serialize;

/// Full-speed bulk packet size.
pub const PACKET: usize = 64;
/// Most bulk packets in one 1 ms full-speed frame.
pub const THEORETICAL_PACKETS_PER_MS: f64 = 19.0;
/// The practical figure the budget uses (module docs).
pub const PRACTICAL_PACKETS_PER_MS: f64 = 10.0;

/// Packets one protocol frame of `len` bytes costs.
pub fn packets(len: usize) -> usize {
    len.div_ceil(PACKET) + usize::from(len.is_multiple_of(PACKET))
}

/// One line's traffic.
#[derive(Clone, Debug, Default, Serialize)]
pub struct LineTraffic {
    /// Protocol frames.
    pub frames: usize,
    /// Bytes on the link (COBS-encoded frames with their delimiters).
    pub bytes: usize,
    /// USB packets.
    pub packets: usize,
}

impl LineTraffic {
    /// Adds a frame of `len` bytes.
    pub fn add(&mut self, len: usize) {
        self.frames += 1;
        self.bytes += len;
        self.packets += packets(len);
    }
    /// Link time of the line at `packets_per_ms`, us.
    pub fn time_us(&self, packets_per_ms: f64) -> f64 {
        self.packets as f64 / packets_per_ms * 1000.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_costs_its_packets_and_a_zero_length_one_on_a_boundary() {
        assert_eq!((packets(1), packets(63), packets(64), packets(65), packets(128)), (1, 1, 2, 2, 3));
        let mut t = LineTraffic::default();
        t.add(100);
        t.add(64);
        assert_eq!((t.frames, t.bytes, t.packets), (2, 164, 4));
        assert!((t.time_us(19.0) - 4.0 / 19.0 * 1000.0).abs() < 1e-9);
    }
}
