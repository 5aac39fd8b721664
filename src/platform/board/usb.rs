//! USB CDC-ACM on the OTG FS port (connector CN7): the same wire protocol the
//! QEMU build carries on USART1, as `embedded_io_async` `Read`/`Write`; and
//! beside it, on the same device, a USB DFU 1.1 interface
//! (`crate::app::usb_dfu`) so that standard `dfu-util -D` can write a signed
//! image into the update partition.
//!
//! The USB VID/PID below are PLACEHOLDERS (0x1209 is pid.codes' open-source
//! vendor ID, 0x0001 its test PID, which must not ship); a product needs its
//! own. The serial number is the chip's 96-bit unique ID in hex, so every
//! instrument enumerates with a stable, distinct serial.
//!
//! Link behaviour, chosen so the application's main loop never stalls on the
//! host (the watchdog is fed by that loop):
//! - reads wait for a host to connect and for data; a disconnect is not an
//!   error to the reader, it just waits again;
//! - writes while the device is not configured by a host are dropped
//!   (reported as [`LinkError::Disconnected`]); a packet the host does not
//!   take within [`WRITE_TIMEOUT`] fails with [`LinkError::Timeout`], and
//!   until the host takes one again every packet gets only
//!   [`STALLED_TIMEOUT`]: a host that opened the port but stopped reading
//!   costs dropped frames, never a stalled pipeline.

use embassy_stm32::Peri;
use embassy_stm32::peripherals::{PA11, PA12, USB_OTG_FS};
use embassy_stm32::usb::Driver;
use embassy_time::{Duration, with_timeout};
use embassy_usb::class::cdc_acm::{BufferedReceiver, CdcAcmClass, Sender, State};
use embassy_usb::class::dfu::dfu_mode::{self, DfuState};
use embassy_usb::driver::EndpointError;
use embassy_usb::{Builder, UsbDevice};
use static_cell::StaticCell;

use super::Irqs;

/// PLACEHOLDER vendor ID (pid.codes open-source VID): replace before shipping.
pub const USB_VID: u16 = 0x1209;
/// PLACEHOLDER product ID (pid.codes test PID 0x0001): replace before shipping.
pub const USB_PID: u16 = 0x0001;
/// Full-speed bulk packet size.
const MAX_PACKET: u16 = 64;
/// The DFU interface's block (`wTransferSize`).
const DFU_BLOCK: usize = crate::app::usb_dfu::BLOCK;
/// How long one packet may wait for the host before the write fails.
pub const WRITE_TIMEOUT: Duration = Duration::from_millis(500);
/// How long a packet may wait while the host is known not to be reading.
pub const STALLED_TIMEOUT: Duration = Duration::from_millis(2);

/// The board's USB driver type.
pub type UsbDriver = Driver<'static, USB_OTG_FS>;

/// The USB port's peripherals, until the device is built.
pub struct UsbPins {
    /// The OTG FS controller.
    pub otg: Peri<'static, USB_OTG_FS>,
    /// D+.
    pub dp: Peri<'static, PA12>,
    /// D-.
    pub dm: Peri<'static, PA11>,
}

/// The USB device and its serial port.
pub struct Usb {
    /// Must be run (forever) by a task for the port to work.
    pub device: UsbDevice<'static, UsbDriver>,
    /// The CDC-ACM port, host to device.
    pub rx: UsbRx,
    /// The CDC-ACM port, device to host.
    pub tx: UsbTx,
}

impl Usb {
    /// Sets up USB OTG FS (PA12 D+, PA11 D-, VBUS sensed on PA9): the
    /// CDC-ACM port and, beside it, the DFU interface served by `dfu`.
    pub fn new<H: dfu_mode::Handler>(pins: UsbPins, dfu: &'static mut DfuState<H>) -> Self {
        static EP_OUT: StaticCell<[u8; 256]> = StaticCell::new();
        static CONFIG_DESC: StaticCell<[u8; 256]> = StaticCell::new();
        static BOS_DESC: StaticCell<[u8; 256]> = StaticCell::new();
        // A DFU block arrives in one control transfer: room for one.
        static CONTROL: StaticCell<[u8; DFU_BLOCK]> = StaticCell::new();
        let UsbPins { otg, dp, dm } = pins;
        static STATE: StaticCell<State<'static>> = StaticCell::new();
        static RX: StaticCell<[u8; MAX_PACKET as usize]> = StaticCell::new();

        let mut otg_config = embassy_stm32::usb::Config::default();
        // The board routes VBUS to PA9 (OTG_FS_VBUS), so unplugging is seen.
        otg_config.vbus_detection = true;
        let driver = Driver::new_fs(otg, Irqs, dp, dm, EP_OUT.init([0; 256]), otg_config);

        let mut config = embassy_usb::Config::new(USB_VID, USB_PID);
        config.manufacturer = Some("BRDF meter project");
        config.product = Some("Gloss/BRDF meter");
        config.serial_number = Some(embassy_stm32::uid::uid_hex());
        config.max_packet_size_0 = 64;
        config.self_powered = false;
        // IAD so Windows binds its CDC driver without an .inf.
        config.device_class = 0xEF;
        config.device_sub_class = 0x02;
        config.device_protocol = 0x01;
        config.composite_with_iads = true;

        let mut builder = Builder::new(
            driver,
            config,
            CONFIG_DESC.init([0; 256]),
            BOS_DESC.init([0; 256]),
            &mut [],
            CONTROL.init([0; DFU_BLOCK]),
        );
        let class = CdcAcmClass::new(&mut builder, STATE.init(State::new()), MAX_PACKET);
        dfu_mode::usb_dfu(&mut builder, dfu, DFU_BLOCK, |_| {});
        let device = builder.build();
        let (tx, rx) = class.split();
        let rx = rx.into_buffered(RX.init([0; MAX_PACKET as usize]));
        Self { device, rx: UsbRx { rx }, tx: UsbTx { tx, last_full: false, host_stalled: false } }
    }
}

/// Why a write to the host failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub enum LinkError {
    /// No host has configured the device: the data was dropped.
    Disconnected,
    /// The host did not take the data within [`WRITE_TIMEOUT`].
    Timeout,
}

impl core::fmt::Display for LinkError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::Disconnected => "no USB host has configured the device",
            Self::Timeout => "the USB host did not take the data in time",
        })
    }
}

impl core::error::Error for LinkError {}

impl embedded_io_async::Error for LinkError {
    fn kind(&self) -> embedded_io_async::ErrorKind {
        match self {
            Self::Disconnected => embedded_io_async::ErrorKind::NotConnected,
            Self::Timeout => embedded_io_async::ErrorKind::TimedOut,
        }
    }
}

/// The receiving half of the CDC-ACM port.
pub struct UsbRx {
    rx: BufferedReceiver<'static, UsbDriver>,
}

/// The sending half of the CDC-ACM port.
pub struct UsbTx {
    tx: Sender<'static, UsbDriver>,
    /// The last packet sent was full: a transfer ends only with a short (or
    /// zero-length) packet, so `flush` sends one.
    last_full: bool,
    /// The last packet timed out: the host is not reading.
    host_stalled: bool,
}

impl UsbTx {
    async fn send(&mut self, packet: &[u8]) -> Result<(), LinkError> {
        let timeout = if self.host_stalled { STALLED_TIMEOUT } else { WRITE_TIMEOUT };
        match with_timeout(timeout, self.tx.write_packet(packet)).await {
            Ok(Ok(())) => {
                self.last_full = packet.len() == MAX_PACKET as usize;
                self.host_stalled = false;
                Ok(())
            }
            Ok(Err(EndpointError::Disabled)) => Err(LinkError::Disconnected),
            // write_packet never gets more than MAX_PACKET bytes from us.
            Ok(Err(EndpointError::BufferOverflow)) => Err(LinkError::Disconnected),
            Err(_) => {
                self.host_stalled = true;
                Err(LinkError::Timeout)
            }
        }
    }
}

impl embedded_io_async::ErrorType for UsbRx {
    type Error = LinkError;
}

impl embedded_io_async::ErrorType for UsbTx {
    type Error = LinkError;
}

impl embedded_io_async::Read for UsbRx {
    async fn read(&mut self, buf: &mut [u8]) -> Result<usize, LinkError> {
        if buf.is_empty() {
            return Ok(0);
        }
        loop {
            self.rx.wait_connection().await;
            match embedded_io_async::Read::read(&mut self.rx, buf).await {
                Ok(0) => continue,
                Ok(n) => return Ok(n),
                // Unplugged or reset by the host: wait for it to come back.
                Err(_) => continue,
            }
        }
    }
}

impl embedded_io_async::Write for UsbTx {
    async fn write(&mut self, buf: &[u8]) -> Result<usize, LinkError> {
        if buf.is_empty() {
            return Ok(0);
        }
        let n = buf.len().min(MAX_PACKET as usize);
        self.send(&buf[..n]).await?;
        Ok(n)
    }

    async fn flush(&mut self) -> Result<(), LinkError> {
        if self.last_full {
            self.send(&[]).await?;
            self.last_full = false;
        }
        Ok(())
    }
}

/// Runs the USB device stack; spawn once.
#[embassy_executor::task]
pub async fn run(mut device: UsbDevice<'static, UsbDriver>) -> ! {
    device.run().await
}
