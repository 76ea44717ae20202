//! The robot's UDP socket (SITL or HIL): every datagram waiting is read
//! without blocking; each MAVLink frame goes out in a datagram of its
//! own.

use std::io::ErrorKind;
use std::net::{SocketAddr, UdpSocket};

use super::address::MavlinkAddress;

/// Largest datagram read (a MAVLink 2 frame is at most 280 bytes; a
/// ground station may pack several into one datagram).
const DATAGRAM_BYTES: usize = 65_536;

/// Counts of the link.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct LinkCounters {
    /// Datagrams received.
    pub datagrams_in: u64,
    /// Bytes received.
    pub bytes_in: u64,
    /// Frames the socket took. Not known to arrive: a frame sent to a
    /// port nobody listens on counts here, since the unconnected socket
    /// gets no error for it.
    pub frames_out: u64,
    /// Frames not sent: the socket refused them (no route, no buffer), or
    /// `udpin:` before any ground station spoke.
    pub frames_unsent: u64,
    /// Datagrams the operating system dropped before the socket read
    /// them (its receive buffer full, e.g. under a flood): Linux's count
    /// for this socket (`drops` in /proc/net/udp); `None` where it cannot
    /// be read.
    pub kernel_dropped_datagrams: Option<u64>,
}

/// The UDP link to the ground station.
#[derive(Debug)]
pub struct UdpLink {
    socket: UdpSocket,
    /// Where frames go: the given address (`udp:`) or the last sender
    /// (`udpin:`).
    peer: Option<SocketAddr>,
    listen: bool,
    buf: Vec<u8>,
    counters: LinkCounters,
}

impl UdpLink {
    /// Opens the socket (non-blocking).
    ///
    /// # Errors
    /// The socket's bind error.
    pub fn open(address: MavlinkAddress) -> anyhow::Result<Self> {
        let (bind, peer, listen) = match address {
            MavlinkAddress::Send(to) => (SocketAddr::new(to.ip(), 0), Some(to), false),
            MavlinkAddress::Listen(at) => (at, None, true),
        };
        let socket = UdpSocket::bind(bind).map_err(|e| anyhow::anyhow!("binding {bind}: {e}"))?;
        socket.set_nonblocking(true)?;
        Ok(Self {
            socket,
            peer,
            listen,
            buf: vec![0; DATAGRAM_BYTES],
            counters: LinkCounters::default(),
        })
    }

    /// The socket's own address.
    ///
    /// # Errors
    /// The socket's error.
    pub fn local_addr(&self) -> anyhow::Result<SocketAddr> {
        Ok(self.socket.local_addr()?)
    }

    /// Where frames go now.
    #[must_use]
    pub fn peer(&self) -> Option<SocketAddr> {
        self.peer
    }

    /// `udp LOCAL -> PEER`, the line a run announces its link with (the
    /// peer "the last sender" for `udpin:` before any ground station
    /// spoke).
    #[must_use]
    pub fn describe(&self) -> String {
        let local = self
            .local_addr()
            .map_or_else(|e| e.to_string(), |a| a.to_string());
        let peer = self
            .peer
            .map_or_else(|| "the last sender".to_string(), |a| a.to_string());
        format!("udp {local} -> {peer}")
    }

    /// The counters, with the operating system's drops read now.
    #[must_use]
    pub fn counters(&self) -> LinkCounters {
        LinkCounters {
            kernel_dropped_datagrams: self.kernel_dropped_datagrams(),
            ..self.counters
        }
    }

    /// The `drops` column of this socket's line (found by its inode) in
    /// /proc/net/udp or /proc/net/udp6.
    fn kernel_dropped_datagrams(&self) -> Option<u64> {
        let inode = rustix::fs::fstat(&self.socket).ok()?.st_ino;
        ["/proc/net/udp", "/proc/net/udp6"]
            .iter()
            .find_map(|table| {
                let table = std::fs::read_to_string(table).ok()?;
                table.lines().skip(1).find_map(|line| {
                    // sl local rem st queues tr:when retrnsmt uid timeout inode
                    // ref pointer drops
                    let fields: Vec<&str> = line.split_whitespace().collect();
                    let this = fields.get(9)?.parse::<u64>().ok()? == inode;
                    if this {
                        fields.last()?.parse().ok()
                    } else {
                        None
                    }
                })
            })
    }

    /// Appends every byte received since the last call to `into`.
    ///
    /// # Errors
    /// A socket error other than "nothing waiting" or a refused earlier
    /// send (the ICMP answer to a datagram nobody took).
    pub fn receive(&mut self, into: &mut Vec<u8>) -> anyhow::Result<()> {
        self.receive_datagrams(|datagram| into.extend_from_slice(datagram))
    }

    /// Hands every datagram received since the last call to `take`, one
    /// at a time, in order.
    ///
    /// # Errors
    /// As [`Self::receive`].
    pub fn receive_datagrams(&mut self, mut take: impl FnMut(&[u8])) -> anyhow::Result<()> {
        loop {
            match self.socket.recv_from(&mut self.buf) {
                Ok((n, from)) => {
                    self.counters.datagrams_in += 1;
                    self.counters.bytes_in += n as u64;
                    take(&self.buf[..n]);
                    if self.listen {
                        self.peer = Some(from);
                    }
                }
                Err(e) if e.kind() == ErrorKind::WouldBlock => return Ok(()),
                Err(e) if e.kind() == ErrorKind::ConnectionRefused => {}
                Err(e) => return Err(anyhow::Error::new(e).context("receiving MAVLink")),
            }
        }
    }

    /// Sends `bytes` (whole MAVLink 2 frames), a datagram per frame.
    pub fn send_frames(&mut self, bytes: &[u8]) {
        let mut rest = bytes;
        while !rest.is_empty() {
            let n = frame_len(rest).min(rest.len());
            let (frame, tail) = rest.split_at(n);
            rest = tail;
            let sent = self
                .peer
                .is_some_and(|to| self.socket.send_to(frame, to).is_ok());
            if sent {
                self.counters.frames_out += 1;
            } else {
                self.counters.frames_unsent += 1;
            }
        }
    }
}

/// The length of the MAVLink frame at the start of `bytes` (MAVLink 2:
/// 12 bytes around the payload, 13 more with a signature; MAVLink 1: 8
/// around it); all of `bytes` where it does not start with a frame.
fn frame_len(bytes: &[u8]) -> usize {
    match (bytes.first(), bytes.get(1), bytes.get(2)) {
        (Some(0xFD), Some(&len), Some(&flags)) => {
            usize::from(len) + 12 + if flags & 1 == 1 { 13 } else { 0 }
        }
        (Some(0xFE), Some(&len), _) => usize::from(len) + 8,
        _ => bytes.len(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_are_split_by_their_length() {
        let mut two = vec![0xFD, 2, 0, 0, 0, 1, 1, 0, 0, 0, 7, 7, 0xAA, 0xBB];
        two.extend([0xFE, 1, 0, 1, 1, 0, 9, 0xAA, 0xBB]);
        assert_eq!(frame_len(&two), 14);
        assert_eq!(frame_len(&two[14..]), 9);
        assert_eq!(frame_len(&[1, 2, 3]), 3);
    }

    /// A flood past the socket's receive buffer: every datagram sent is
    /// either read or counted as dropped by the operating system
    /// (loopback delivers to the buffer as it sends, so none is lost
    /// elsewhere).
    #[cfg(target_os = "linux")]
    #[test]
    fn datagrams_the_kernel_drops_are_counted() {
        let mut link =
            UdpLink::open(MavlinkAddress::Listen("127.0.0.1:0".parse().unwrap())).unwrap();
        assert_eq!(link.counters().kernel_dropped_datagrams, Some(0));
        let to = link.local_addr().unwrap();
        let sender = UdpSocket::bind("127.0.0.1:0").unwrap();
        // Far more than a receive buffer (at most a few MB) holds.
        let sent = 10_000_u64;
        for _ in 0..sent {
            sender.send_to(&[0x55; 1000], to).unwrap();
        }
        link.receive_datagrams(|_| {}).unwrap();
        let counters = link.counters();
        let dropped = counters.kernel_dropped_datagrams.unwrap();
        assert!(dropped > 0, "{counters:?}");
        assert_eq!(counters.datagrams_in + dropped, sent, "{counters:?}");
    }
}
