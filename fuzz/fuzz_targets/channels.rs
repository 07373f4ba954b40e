//! The channels decoder (`ratf_protocol::channels::Decoder`) on any bytes from the wire:
//! every frame it completes re-encodes to nine bytes that decode to the same frame, its
//! counters agree with what it delivered, and the frames do not depend on how the bytes
//! were chunked.
#![no_main]

use libfuzzer_sys::fuzz_target;
use ratf_protocol::channels::{Decoder, FRAME_LEN, Frame};

fn frames(chunks: &[&[u8]]) -> (Vec<Frame>, Decoder) {
    let mut decoder = Decoder::new();
    let mut out = Vec::new();
    for chunk in chunks {
        decoder.feed(chunk, |frame| out.push(frame));
    }
    (out, decoder)
}

fuzz_target!(|data: &[u8]| {
    let Some((&split, bytes)) = data.split_first() else {
        return;
    };
    let (whole, decoder) = frames(&[bytes]);
    assert_eq!(decoder.stats().frames as usize, whole.len());
    let at = usize::from(split).min(bytes.len());
    let (chunked, _) = frames(&[&bytes[..at], &bytes[at..]]);
    assert_eq!(whole, chunked, "chunking at {at} changed the frames");
    for frame in whole {
        let wire = frame.encode();
        assert_eq!(wire.len(), FRAME_LEN);
        let (again, _) = frames(&[&wire]);
        assert_eq!(again, [frame], "{:?} does not round-trip", wire);
    }
});
