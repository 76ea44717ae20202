//! Telemetry on the defmt log, the same on both boards: a start line when
//! a run starts, then one record per emitted tick (`wmr_link::telemetry`
//! has the fields, their units and the text form a decoder prints, which
//! `firmware-sim plot` reads back).
//!
//! `defmt::println!`, not a levelled macro: telemetry is data, kept
//! whatever `DEFMT_LOG` filters. One format string per line, so that a
//! record costs one call per field and a few hundred bytes of flash in
//! all (the strings live in the ELF's defmt table, not in flash).

use wmr_link::telemetry::{FORMAT_VERSION, Record, Start};

/// Logs the start of a run's telemetry.
#[inline(never)]
pub fn start(s: Start) {
    defmt::println!(
        "wmr-tlm-start {=u32} {=u16} {=f32}",
        FORMAT_VERSION,
        s.every_ticks,
        s.period_s
    );
}

/// Logs one tick's record.
#[inline(never)]
pub fn record(r: &Record) {
    defmt::println!(
        "wmr-tlm {=u32} {=u32} {=u8} {=u8} {=f32} {=f32} {=f32} {=f32} {=f32} {=f32} {=f32} {=f32} {=f32} {=f32} {=u32} {=u32} {=u32}",
        FORMAT_VERSION,
        r.tick,
        r.mode,
        r.flags,
        r.reference_m[0],
        r.reference_m[1],
        r.position_m[0],
        r.position_m[1],
        r.heading[0],
        r.heading[1],
        r.command[0],
        r.command[1],
        r.duty[0],
        r.duty[1],
        r.ticks_since_fix,
        r.fixes_used,
        r.device_faults
    );
}
