//! The `--mavlink` address: `udp:HOST:PORT` (the robot, SITL or HIL,
//! sends to a ground station listening there) or `udpin:HOST:PORT` (it
//! listens there and answers whoever sent last), and the loopback rule.

use std::net::{SocketAddr, ToSocketAddrs};

/// How the SITL's UDP socket meets the ground station.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MavlinkAddress {
    /// `udp:HOST:PORT`: the ground station listens at the address (as
    /// QGroundControl does on 14550); the SITL binds an ephemeral port on
    /// the same interface, sends every frame to the address and takes
    /// frames from any sender on its port (PX4's SITL and ArduPilot's
    /// `udpclient:` do the same).
    Send(SocketAddr),
    /// `udpin:HOST:PORT`: the SITL binds the address and answers the last
    /// sender (nothing is sent before a ground station has spoken).
    Listen(SocketAddr),
}

impl MavlinkAddress {
    /// Parses `udp:HOST:PORT` or `udpin:HOST:PORT`. Without
    /// `allow_non_loopback`, an address outside the loopback range
    /// (127.0.0.0/8, ::1) is refused, so that a simulated robot is never
    /// reachable from the network by accident; with it, any address is
    /// taken (`udpin:0.0.0.0:14550` to serve a ground station on another
    /// machine).
    ///
    /// # Errors
    /// A scheme other than `udp` or `udpin`, an address that does not
    /// resolve, or one outside loopback without `allow_non_loopback`.
    pub fn parse(text: &str, allow_non_loopback: bool) -> anyhow::Result<Self> {
        let (scheme, rest) = text.split_once(':').ok_or_else(|| {
            anyhow::anyhow!("--mavlink {text}: expected udp:HOST:PORT or udpin:HOST:PORT")
        })?;
        let addr = rest
            .to_socket_addrs()
            .map_err(|e| anyhow::anyhow!("--mavlink {text}: {e}"))?
            .next()
            .ok_or_else(|| anyhow::anyhow!("--mavlink {text}: resolves to no address"))?;
        let ip = addr.ip();
        if !allow_non_loopback && !ip.is_loopback() {
            anyhow::bail!(
                "--mavlink {text}: {ip} is not a loopback address (127.0.0.0/8, ::1); \
                 add --allow-non-loopback to serve another machine"
            );
        }
        match scheme {
            "udp" => {
                if addr.port() == 0 || ip.is_unspecified() {
                    anyhow::bail!(
                        "--mavlink {text}: udp: sends to this address; give a host and a port"
                    );
                }
                Ok(Self::Send(addr))
            }
            "udpin" => Ok(Self::Listen(addr)),
            other => anyhow::bail!("--mavlink {text}: scheme {other:?}: expected udp or udpin"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loopback_only_unless_allowed() {
        assert!(matches!(
            MavlinkAddress::parse("udp:127.0.0.1:14550", false),
            Ok(MavlinkAddress::Send(a)) if a.port() == 14550
        ));
        assert!(matches!(
            MavlinkAddress::parse("udpin:127.0.0.1:0", false),
            Ok(MavlinkAddress::Listen(_))
        ));
        let refused = MavlinkAddress::parse("udpin:0.0.0.0:14550", false);
        assert!(refused.unwrap_err().to_string().contains("not a loopback"));
        assert!(matches!(
            MavlinkAddress::parse("udpin:0.0.0.0:14550", true),
            Ok(MavlinkAddress::Listen(_))
        ));
        assert!(MavlinkAddress::parse("tcp:127.0.0.1:5760", false).is_err());
        assert!(MavlinkAddress::parse("udp:127.0.0.1:0", false).is_err());
        assert!(MavlinkAddress::parse("127.0.0.1", false).is_err());
    }
}
