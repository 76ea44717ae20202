//! The size harness (see Cargo.toml): reads its inputs from volatile
//! statics so that nothing is folded away.
#![no_std]
#![no_main]
use core::ptr::{read_volatile, write_volatile};
#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    loop {}
}
static mut RX: [u8; 64] = [0; 64];
static mut OUT: [u8; 512] = [0; 512];
static mut WORDS: [u32; 8] = [0; 8];
fn word(i: usize) -> u32 {
    unsafe { read_volatile(&raw const WORDS[i]) }
}
fn rx() -> [u8; 64] {
    unsafe { read_volatile(&raw const RX) }
}
fn emit(b: &[u8], n: u32) {
    let mut o = [0u8; 512];
    let k = b.len().min(512);
    o[..k].copy_from_slice(&b[..k]);
    unsafe {
        write_volatile(&raw mut OUT, o);
        write_volatile(&raw mut WORDS[7], n)
    }
}

#[cfg(feature = "endpoint")]
#[unsafe(no_mangle)]
pub extern "C" fn _start() -> ! {
    use wmr_core::reference::route::{RouteError, Waypoints};
    use wmr_mavlink::*;
    let spec = EndpointSpec {
        origin_e7: Some((word(0) as i32, word(1) as i32)),
        ..EndpointSpec::default()
    };
    let Ok(cfg) = EndpointConfig::new(&spec) else {
        loop {}
    };
    let Some(limits) = limits() else { loop {} };
    let mut ep = MavlinkEndpoint::new(cfg, limits);
    loop {
        let bytes = rx();
        let w = word(2);
        let view = RobotView {
            armed: w & 1 != 0,
            mode: match w >> 1 & 3 {
                0 => RobotMode::Idle,
                1 => RobotMode::Running,
                2 => RobotMode::Paused,
                _ => RobotMode::Done,
            },
            estimate: Some(Estimate {
                x_m: f32::from_bits(word(3)),
                y_m: f32::from_bits(word(4)),
                heading_rad: f32::from_bits(word(5)),
                speed_m_s: 0.1,
                turn_rate_rad_s: 0.0,
            }),
            current: (w >> 8) as u16,
            reached: if w & 0x80 != 0 {
                Some((w >> 16) as u16)
            } else {
                None
            },
        };
        let mut buf = [0u8; 512];
        let mut tx = TxBuffer::new(&mut buf);
        let check = |r: &Waypoints| {
            if r.len() < 2 {
                Err(RouteError::TooFewWaypoints)
            } else {
                Ok(())
            }
        };
        let events = ep.handle(
            word(6),
            &bytes[..(w as usize >> 24) % 64],
            &view,
            check,
            &mut tx,
        );
        let mut n = events.as_slice().len() as u32;
        if events.as_slice().contains(&Event::LoadRoute) {
            let r = ep.route();
            n += r.as_slice().first().map_or(0, |p| p.position_m.x.to_bits());
        }
        emit(tx.as_slice(), n ^ shared());
    }
}

/// Route limits from volatile words (a firmware checks its robot file's).
fn limits() -> Option<wmr_core::reference::route::RouteLimits> {
    use wmr_core::reference::route::{RouteLimits, RouteLimitsSpec};
    let f = |i| f32::from_bits(word(i));
    RouteLimits::new(&RouteLimitsSpec {
        max_speed_m_s: f(0),
        max_tangential_accel_m_s2: f(1),
        max_lateral_accel_m_s2: f(2),
        blend_deviation_m: f(3),
        pivot_threshold_rad: f(4),
        pivot_rate_rad_s: f(5),
        pivot_accel_rad_s2: f(6),
    })
    .ok()
}

/// What a firmware with the core links already: the core's sin, cos,
/// sqrt, angle wrap, memcpy / memmove / memset (and, above, the route
/// limits' check).
fn shared() -> u32 {
    use wmr_core::math;
    let x = f32::from_bits(word(3));
    let mut big = [0u8; 600];
    big[word(4) as usize % 600] = 1;
    let (a, b) = ((word(5) as usize) % 300, (word(6) as usize) % 300);
    big.copy_within(a..a + 200, b);
    (math::sin(x) + math::cos(x) + math::sqrt(x) + math::wrap_angle(x)).to_bits()
        ^ u32::from(big[(word(0) as usize) % 600])
}

#[cfg(feature = "endpoint")]
#[unsafe(no_mangle)]
pub extern "C" fn shared_entry() -> u32 {
    shared()
}

#[cfg(not(feature = "endpoint"))]
#[unsafe(no_mangle)]
pub extern "C" fn _start() -> ! {
    loop {
        let bytes = rx();
        let speed = limits().map_or(0, |l| l.max_speed_m_s().to_bits());
        emit(
            &bytes[..(word(2) as usize >> 24) % 64],
            word(6) ^ shared() ^ speed,
        );
    }
}
