//! Stack use of one call, by painting (item 5 of the bench's documentation,
//! `main.rs`).

/// Bytes painted below the stack pointer before a stack-measured tick
/// (the nRF51 has 16 KiB of RAM in all).
const STACK_WINDOW_BYTES: usize = if cfg!(target_abi = "eabihf") {
    16 * 1024
} else {
    8 * 1024
};

/// Bytes of stack `f` uses below this function's stack pointer; `None`
/// if it used the whole painted window. `f` should be one call of an
/// `#[inline(never)]` function (its arguments prepared by the caller).
#[inline(never)]
pub(super) fn stack_bytes(f: impl FnOnce()) -> Option<u32> {
    let paint = cortex_m_rt::STACK_PAINT_VALUE;
    // The stack region's low end: cortex-m-rt's linker symbol (set by
    // flip-link too, when the stack is placed below the statics); only
    // its address is used.
    #[allow(unsafe_code)]
    unsafe extern "C" {
        static _stack_end: u32;
    }
    let floor = (&raw const _stack_end) as usize;
    let sp = cortex_m::register::msp::read() as usize;
    let window = STACK_WINDOW_BYTES.min(sp.saturating_sub(floor)) & !3;
    let bottom = sp - window;
    // SAFETY: writes `paint` to the words of [bottom, sp): free stack
    // below this function's frame (the stack pointer of a Rust function
    // does not move after its prologue) and above the statics; no
    // interrupt is enabled, so nothing else uses that memory now. The
    // loop uses registers only.
    #[allow(unsafe_code)]
    unsafe {
        core::arch::asm!(
            "2:",
            "cmp {p}, {top}",
            "bhs 3f",
            "str {v}, [{p}]",
            "adds {p}, {p}, #4",
            "b 2b",
            "3:",
            p = inout(reg) bottom => _,
            top = in(reg) sp,
            v = in(reg) paint,
            options(nostack),
        );
    }
    f();
    let mut addr = bottom;
    while addr < sp {
        // SAFETY: `addr` is word-aligned (sp is, and the window is a
        // multiple of 4) and inside the RAM just painted; a volatile
        // read of RAM has no side effects.
        #[allow(unsafe_code)]
        let word = unsafe { core::ptr::read_volatile(addr as *const u32) };
        if word != paint {
            break;
        }
        addr += 4;
    }
    (addr > bottom).then(|| u32::try_from(sp - addr).unwrap_or(u32::MAX))
}
