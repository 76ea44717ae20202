//! Arbitrary bytes into the link's decoder, both ways:
//!
//! 1. as one frame's COBS bytes, into `decode` for either side's message;
//! 2. as the payload of a frame that the harness frames correctly itself
//!    (CRC-32/ISO-HDLC appended, COBS), so that postcard's decoder sees
//!    arbitrary bytes past the CRC check: the framing must be transparent
//!    (the frame decodes exactly as postcard decodes the payload);
//! 3. as a byte stream into the firmware's `Receiver`.
//!
//! Whatever decodes must encode again into one frame of at most
//! `MAX_FRAME_BYTES`, and that frame must decode to the same encoding.

#![no_main]

use libfuzzer_sys::fuzz_target;
use serde::Serialize;
use serde::de::DeserializeOwned;
use wmr_link::{
    Frame, HostMessage, LinkError, MAX_FRAME_BYTES, Receiver, TargetMessage, decode, encode,
};

/// The message re-encoded: one frame, no zero inside, ends in zero, fits;
/// and decoding it gives the same bytes again (a stable round trip; bytes
/// rather than values because NaN != NaN).
fn re_encodes<M: Serialize + DeserializeOwned>(frame: &Frame<M>) {
    let mut out = [0; MAX_FRAME_BYTES];
    let bytes = encode(frame, &mut out)
        .expect("a decoded message must fit in a frame")
        .to_vec();
    assert!(bytes.len() <= MAX_FRAME_BYTES);
    let (last, body) = bytes.split_last().expect("a frame is never empty");
    assert_eq!(*last, 0);
    assert!(!body.contains(&0));
    let mut again = body.to_vec();
    let decoded: Frame<M> = decode(&mut again).expect("an encoded frame must decode");
    let mut out2 = [0; MAX_FRAME_BYTES];
    assert_eq!(encode(&decoded, &mut out2).map(<[u8]>::to_vec), Ok(bytes));
}

/// 1: the bytes as one frame.
fn as_frame<M: Serialize + DeserializeOwned>(data: &[u8]) {
    let mut buf = data.to_vec();
    if let Ok(frame) = decode::<M>(&mut buf) {
        re_encodes(&frame);
    }
}

/// 2: the bytes as a correctly framed payload.
fn as_payload<M: Serialize + DeserializeOwned + core::fmt::Debug>(data: &[u8]) {
    const CRC: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);
    let mut raw = data.to_vec();
    raw.extend_from_slice(&CRC.checksum(data).to_le_bytes());
    let mut cobs_bytes = vec![0; cobs::max_encoding_length(raw.len())];
    let n = cobs::encode(&raw, &mut cobs_bytes);
    cobs_bytes.truncate(n);
    assert!(!cobs_bytes.contains(&0));
    let got = decode::<M>(&mut cobs_bytes);
    let want = postcard::from_bytes::<Frame<M>>(data);
    match (&got, &want) {
        (Ok(g), Ok(w)) => {
            let mut a = [0; MAX_FRAME_BYTES];
            let mut b = [0; MAX_FRAME_BYTES];
            assert_eq!(
                encode(g, &mut a).map(<[u8]>::to_vec),
                encode(w, &mut b).map(<[u8]>::to_vec)
            );
            re_encodes(g);
        }
        (Err(LinkError::Decode), Err(_)) => {}
        _ => panic!("framing is not transparent: decode gave {got:?}, postcard {want:?}"),
    }
}

/// 3: the bytes as a stream into the receiver.
fn as_stream<M: Serialize + DeserializeOwned>(data: &[u8]) {
    let mut rx = Receiver::new();
    let mut results = 0_u32;
    let mut ok = 0_u32;
    for &b in data {
        if let Some(r) = rx.push::<M>(b) {
            results += 1;
            if let Ok(body) = r {
                ok += 1;
                re_encodes(&Frame { seq: 0, body });
            }
        }
    }
    let c = rx.counters();
    assert_eq!(c.frames_ok, ok);
    // Every frame is accepted, corrupt, or stale (a sequence number behind
    // the last accepted one), and counted as such.
    assert_eq!(c.frames_ok + c.corrupt_frames + c.stale_frames, results);
}

fuzz_target!(|data: &[u8]| {
    as_frame::<HostMessage>(data);
    as_frame::<TargetMessage>(data);
    as_payload::<HostMessage>(data);
    as_payload::<TargetMessage>(data);
    as_stream::<HostMessage>(data);
    as_stream::<TargetMessage>(data);
});
