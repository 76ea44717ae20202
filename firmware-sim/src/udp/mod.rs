//! A ground station's UDP side, shared by `firmware-sim sitl` and
//! `firmware-sim hil --mavlink` (docs/mavlink.md): the `--mavlink`
//! address and the loopback rule ([`address`]), the non-blocking socket
//! that takes datagrams and sends a datagram per MAVLink frame ([`link`]),
//! and the wall clock a run keeps to, `N` times real time ([`pace`]).
//! Files, each using only those above it; nothing else of this crate.

pub mod address;
pub mod link;
pub mod pace;

pub use address::MavlinkAddress;
pub use link::{LinkCounters, UdpLink};
pub use pace::Pace;
