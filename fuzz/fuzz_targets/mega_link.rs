//! The host's Mega link (`ratf_core::drivers::mega_link::MegaLink`) on any bytes, then one
//! sealed telemetry batch: what the noise yields does not depend on its chunking, and once
//! a separator and a checksum frame have closed the damaged batch, the sealed batch comes
//! out as exactly one telemetry event carrying its tick totals, loop period and switch.
#![no_main]

use libfuzzer_sys::fuzz_target;
use ratf_core::drivers::mega_link::{MegaEvent, MegaLink};
use ratf_protocol::channels::Frame;
use ratf_protocol::integrity::{BatchWriter, MCU_CHECKSUM_CHANNEL};
use ratf_protocol::messages::{Telemetry, Wheel};

fn events(link: &mut MegaLink, bytes: &[u8]) -> Vec<MegaEvent> {
    let mut out = Vec::new();
    link.feed(bytes, 1_000_000, |e| out.push(e));
    out
}

fuzz_target!(|data: &[u8]| {
    // 4 totals, the period, the switch; then the split point; then the noise.
    if data.len() < 22 {
        return;
    }
    let (fields, rest) = data.split_at(22);
    let word = |i: usize| {
        u32::from_le_bytes([
            fields[4 * i],
            fields[4 * i + 1],
            fields[4 * i + 2],
            fields[4 * i + 3],
        ])
    };
    let totals = [
        word(0) as i32,
        word(1) as i32,
        word(2) as i32,
        word(3) as i32,
    ];
    let period_us = word(4);
    let pressed = fields[20] & 1 == 1;
    let split = usize::from(fields[21]).min(rest.len());

    let mut link = MegaLink::default();
    let whole = events(&mut link, rest);
    let mut chunked_link = MegaLink::default();
    let mut chunked = events(&mut chunked_link, &rest[..split]);
    chunked.extend(events(&mut chunked_link, &rest[split..]));
    assert_eq!(whole, chunked, "chunking at {split} changed the events");
    assert_eq!(link.stats(), chunked_link.stats());

    // A separator ends any frame under way; a checksum frame closes the damaged batch.
    let _ = events(&mut link, b" z00000000");
    let mut frames: Vec<Frame> = Wheel::ALL
        .iter()
        .zip(totals)
        .map(|(&wheel, total)| Telemetry::Ticks { wheel, total }.to_frame())
        .collect();
    frames.push(Telemetry::LoopPeriod { period_us }.to_frame());
    frames.push(Telemetry::Switch { pressed }.to_frame());
    let mut writer = BatchWriter::new(MCU_CHECKSUM_CHANNEL, true);
    let mut wire = vec![0; writer.batch_len(frames.len())];
    let n = writer
        .write_batch(&frames, &mut wire)
        .expect("room for the batch");
    let sealed = events(&mut link, &wire[..n]);
    match sealed.as_slice() {
        [MegaEvent::Telemetry(t)] => {
            assert_eq!(t.totals, totals);
            assert_eq!(t.period_us, period_us);
            assert_eq!(t.switch_pressed, pressed);
        }
        other => panic!("a sealed batch after noise gave {other:?}"),
    }
});
