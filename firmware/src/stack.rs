//! Stack high-water mark by painting.
//!
//! cortex-m-rt's `paint-stack` feature fills the whole stack region,
//! `_stack_end ..= _stack_start` (from the end of `.bss` to the top of RAM),
//! with [`cortex_m_rt::STACK_PAINT_VALUE`] before `main`. The deepest use
//! since reset is the distance from the top of the stack to the lowest word
//! no longer holding the paint.

/// Deepest stack use since reset, bytes (a lower bound: a frame that wrote
/// exactly the paint value would be missed, which real frames do not).
pub fn peak_bytes() -> u32 {
    // Linker symbols of cortex-m-rt's `link.x`; only their addresses are used.
    #[allow(unsafe_code)]
    unsafe extern "C" {
        static _stack_end: u32;
        static _stack_start: u32;
    }
    let bottom = (&raw const _stack_end) as usize;
    let top = (&raw const _stack_start) as usize;
    let mut addr = bottom;
    while addr < top {
        // SAFETY: `addr` is word-aligned (cortex-m-rt aligns `_stack_end` to
        // 4) and lies in the RAM region reserved for the stack, which is
        // always mapped; a volatile read of it has no side effects.
        #[allow(unsafe_code)]
        let word = unsafe { core::ptr::read_volatile(addr as *const u32) };
        if word != cortex_m_rt::STACK_PAINT_VALUE {
            break;
        }
        addr += 4;
    }
    u32::try_from(top - addr).unwrap_or(u32::MAX)
}
