//! The few STM32L475 registers the QEMU layer touches (RM0351), always with
//! 32-bit volatile accesses (QEMU's L4 USART rejects narrower ones).
pub const RCC: usize = 0x4002_1000;
pub const RCC_AHB2ENR: usize = RCC + 0x4C;
pub const RCC_AHB2ENR_GPIOEEN: u32 = 1 << 4;
pub const RCC_AHB2ENR_GPIOAEN: u32 = 1 << 0;
pub const RCC_APB2ENR: usize = RCC + 0x60;
pub const RCC_APB2ENR_USART1EN: u32 = 1 << 14;

pub const GPIOA: usize = 0x4800_0000;
pub const GPIOE: usize = 0x4800_1000;
pub const GPIO_MODER: usize = 0x00;
pub const GPIO_ODR: usize = 0x14;
pub const GPIO_BSRR: usize = 0x18;

pub const USART1: usize = 0x4001_3800;
pub const USART_CR1: usize = 0x00;
pub const USART_BRR: usize = 0x0C;
pub const USART_ISR: usize = 0x1C;
pub const USART_ICR: usize = 0x20;
pub const USART_RDR: usize = 0x24;
pub const USART_TDR: usize = 0x28;
pub const CR1_UE: u32 = 1 << 0;
pub const CR1_RE: u32 = 1 << 2;
pub const CR1_TE: u32 = 1 << 3;
pub const CR1_RXNEIE: u32 = 1 << 5;
pub const ISR_ORE: u32 = 1 << 3;
pub const ISR_RXNE: u32 = 1 << 5;
pub const ISR_TXE: u32 = 1 << 7;
/// USART1 global interrupt (STM32L475 vector table position).
pub const USART1_IRQN: u16 = 37;

/// Reads a 32-bit register.
///
/// # Safety
/// `addr` must be a readable device register.
#[inline(always)]
pub unsafe fn read(addr: usize) -> u32 {
    unsafe { core::ptr::read_volatile(addr as *const u32) }
}

/// Writes a 32-bit register.
///
/// # Safety
/// `addr` must be a writable device register and the value valid for it.
#[inline(always)]
pub unsafe fn write(addr: usize, v: u32) {
    unsafe { core::ptr::write_volatile(addr as *mut u32, v) }
}

/// Read-modify-write of a 32-bit register.
///
/// # Safety
/// As [`write`]; the caller excludes concurrent writers of the register.
#[inline(always)]
pub unsafe fn modify(addr: usize, f: impl FnOnce(u32) -> u32) {
    unsafe { write(addr, f(read(addr))) }
}
