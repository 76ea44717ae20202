//! STM32F411 "Black Pill" board (being written).

/// The firmware.
pub fn run() -> ! {
    loop {
        cortex_m::asm::wfi();
    }
}
