//! USART1 as the transport. Receive is interrupt-driven into a pipe; when the
//! pipe is full the interrupt is masked and the byte stays in RDR, so QEMU
//! holds the rest (its USART accepts no byte while RXNE is set): nothing is
//! lost, the host is simply slowed down. Transmit polls TXE (QEMU sends at
//! once). All register accesses are 32-bit.
use super::regs::*;
use core::convert::Infallible;
use cortex_m::peripheral::NVIC;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex as Cs;
use embassy_sync::pipe::Pipe;

static RX: Pipe<Cs, 1024> = Pipe::new();

/// The receiving half.
pub struct UsartRx(());
/// The transmitting half.
pub struct UsartTx(());

#[derive(Clone, Copy, Debug)]
struct Irq;
// SAFETY: the USART1 interrupt number of the STM32L475.
unsafe impl cortex_m::interrupt::InterruptNumber for Irq {
    fn number(self) -> u16 {
        USART1_IRQN
    }
}

/// Enables USART1 (8N1; the baud rate is meaningless in QEMU but set sanely)
/// and its receive interrupt.
pub fn init() -> (UsartRx, UsartTx) {
    // SAFETY: boot-time configuration of USART1, owned by this module.
    unsafe {
        write(USART1 + USART_CR1, 0);
        write(USART1 + USART_BRR, super::time_driver::CORE_HZ / 115_200);
        write(USART1 + USART_CR1, CR1_UE | CR1_RE | CR1_TE | CR1_RXNEIE);
        NVIC::unmask(Irq);
    }
    (UsartRx(()), UsartTx(()))
}

/// Moves received bytes into the pipe while it has room; masks itself when
/// it has none (the reader unmasks it).
fn on_interrupt() {
    // SAFETY: ISR-side access to USART1's status and data registers.
    unsafe {
        loop {
            let isr = read(USART1 + USART_ISR);
            if isr & ISR_ORE != 0 {
                write(USART1 + USART_ICR, ISR_ORE);
            }
            if isr & ISR_RXNE == 0 {
                break;
            }
            if RX.free_capacity() == 0 {
                modify(USART1 + USART_CR1, |v| v & !CR1_RXNEIE);
                break;
            }
            let b = read(USART1 + USART_RDR) as u8;
            let _ = RX.try_write(&[b]);
        }
    }
}

/// Interrupt dispatch. Without a device crate, cortex-m-rt binds every
/// device interrupt to `DefaultHandler` with its number: USART1 is the only
/// one this firmware enables.
#[cortex_m_rt::exception]
unsafe fn DefaultHandler(irqn: i16) {
    if irqn == USART1_IRQN as i16 {
        on_interrupt();
    } else {
        panic!("unexpected interrupt {irqn}");
    }
}

impl embedded_io_async::ErrorType for UsartRx {
    type Error = Infallible;
}

impl embedded_io_async::Read for UsartRx {
    async fn read(&mut self, buf: &mut [u8]) -> Result<usize, Infallible> {
        let n = RX.read(buf).await;
        // Room again: let the interrupt take the bytes QEMU is holding.
        cortex_m::interrupt::free(|_| unsafe { modify(USART1 + USART_CR1, |v| v | CR1_RXNEIE) });
        Ok(n)
    }
}

impl embedded_io_async::ErrorType for UsartTx {
    type Error = Infallible;
}

impl embedded_io_async::Write for UsartTx {
    async fn write(&mut self, buf: &[u8]) -> Result<usize, Infallible> {
        for &b in buf {
            // SAFETY: USART1 transmit registers, owned by this half.
            unsafe {
                while read(USART1 + USART_ISR) & ISR_TXE == 0 {}
                write(USART1 + USART_TDR, b as u32);
            }
        }
        Ok(buf.len())
    }
    async fn flush(&mut self) -> Result<(), Infallible> {
        Ok(())
    }
}
