//! Large statics built where they live. A value built on the stack and
//! moved into its static (as `StaticCell::init` does) takes its size of
//! stack first; in the frame of a `main` that never returns it takes it
//! for good, and the stack is 16 KiB (memory.x). The firmware zeroes its
//! RAM copy of the matrices this way ([`crate::estimate::zeroed_in_place`]),
//! the benches their lines and readings.

/// `slot` zeroed where it is, as a `T`.
///
/// # Safety
/// All-zero bytes must be a value of `T`: integers, `bool`s, `f32`s and
/// arrays and structs of them (no references, no enums without a zero
/// variant).
pub unsafe fn zeroed<T>(slot: &mut core::mem::MaybeUninit<T>) -> &mut T {
    // SAFETY: `slot` is valid for writes of one `T`; the caller promises
    // zero bytes are one.
    unsafe {
        core::ptr::write_bytes(slot.as_mut_ptr(), 0, 1);
        slot.assume_init_mut()
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_slot_is_zeroed_whatever_it_held() {
        let mut slot = core::mem::MaybeUninit::new([7u32; 16]);
        // SAFETY: zeros are u32s.
        assert_eq!(*unsafe { super::zeroed(&mut slot) }, [0; 16]);
    }
}
