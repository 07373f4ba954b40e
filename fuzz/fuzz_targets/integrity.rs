//! The integrity receiver (`ratf_protocol::integrity::BatchReceiver`) on any bytes, then a
//! sealed batch: whatever came before, once a separator and one checksum frame have closed
//! the damaged batch, the next two sealed batches are delivered exactly, frame for frame;
//! the frames delivered from the noise do not depend on its chunking; and the counters
//! agree with what was delivered.
#![no_main]

use libfuzzer_sys::fuzz_target;
use ratf_protocol::channels::{Frame, is_channel_letter};
use ratf_protocol::integrity::{BatchReceiver, BatchWriter, MCU_CHECKSUM_CHANNEL};

/// The receiver's capacity, frames (the host's Mega link holds 16).
const CAPACITY: usize = 16;

/// Up to `CAPACITY` frames drawn from `bytes` (5 bytes each: letter, value), none on the
/// checksum channel.
fn batch(bytes: &[u8]) -> Vec<Frame> {
    bytes
        .chunks_exact(5)
        .take(CAPACITY)
        .filter_map(|c| {
            let letter = c[0];
            if !is_channel_letter(letter) || letter == MCU_CHECKSUM_CHANNEL {
                return None;
            }
            Frame::new(letter, u32::from_le_bytes([c[1], c[2], c[3], c[4]])).ok()
        })
        .collect()
}

fuzz_target!(|data: &[u8]| {
    if data.len() < 2 {
        return;
    }
    let noise_len = usize::from(data[0]).min(data.len() - 1);
    let split = usize::from(data[1]);
    let noise = &data[2.min(data.len())..(2 + noise_len).min(data.len())];
    let frames = batch(&data[(2 + noise_len).min(data.len())..]);

    let mut receiver = BatchReceiver::<CAPACITY>::new(MCU_CHECKSUM_CHANNEL);
    let mut delivered = Vec::new();
    receiver.feed(noise, |f| delivered.push(f));
    let mut chunked = BatchReceiver::<CAPACITY>::new(MCU_CHECKSUM_CHANNEL);
    let mut chunked_delivered = Vec::new();
    let at = split.min(noise.len());
    chunked.feed(&noise[..at], |f| chunked_delivered.push(f));
    chunked.feed(&noise[at..], |f| chunked_delivered.push(f));
    assert_eq!(
        delivered, chunked_delivered,
        "chunking at {at} changed the frames"
    );
    assert_eq!(receiver.stats(), chunked.stats());

    // A separator ends any frame under way; a checksum frame closes the damaged batch.
    receiver.feed(b" z00000000", |f| delivered.push(f));
    let before = delivered.len();
    let mut writer = BatchWriter::new(MCU_CHECKSUM_CHANNEL, true);
    let mut wire = vec![0; writer.batch_len(frames.len()) * 2];
    let first = writer
        .write_batch(&frames, &mut wire)
        .expect("room for the batch");
    let second = writer
        .write_batch(&frames, &mut wire[first..])
        .expect("room for the batch");
    receiver.feed(&wire[..first + second], |f| delivered.push(f));
    let expected: Vec<Frame> = frames.iter().chain(&frames).copied().collect();
    assert_eq!(
        &delivered[before..],
        &expected[..],
        "sealed batches after noise"
    );
    assert_eq!(receiver.stats().frames_delivered as usize, delivered.len());
});
