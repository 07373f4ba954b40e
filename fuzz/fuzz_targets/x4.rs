//! The X4's parsers on any bytes from the lidar's port: the scan packet parser
//! (`ratf_core::drivers::x4::parser::PacketParser`) and the reply parser of its device
//! information and health (`info::ReplyParser`). What each finds in the noise does not
//! depend on its chunking, the packets it verifies have a matching check code, and a packet
//! and a reply encoded from the input come back exactly from a fresh parser.
#![no_main]

use libfuzzer_sys::fuzz_target;
use ratf_core::drivers::x4::info::{DeviceInfo, Health, HealthStatus, Reply, ReplyParser};
use ratf_core::drivers::x4::packet::{Packet, PacketSpec, encode_packet};
use ratf_core::drivers::x4::parser::{Event, PacketParser};

/// Every verified packet's bytes, and the count of bad check codes, over `chunks`.
fn packets(chunks: &[&[u8]]) -> (Vec<Vec<u8>>, usize) {
    let mut parser = PacketParser::new();
    let (mut ok, mut bad) = (Vec::new(), 0);
    for chunk in chunks {
        parser.feed(chunk, |event| match event {
            Event::Packet(packet) => ok.push(packet.bytes().to_vec()),
            Event::ChecksumError => bad += 1,
        });
    }
    assert_eq!(parser.stats().packets_ok as usize, ok.len());
    (ok, bad)
}

fn replies(chunks: &[&[u8]]) -> Vec<Reply> {
    let mut parser = ReplyParser::new();
    let mut out = Vec::new();
    for chunk in chunks {
        parser.feed(chunk, |reply| out.push(reply));
    }
    out
}

fuzz_target!(|data: &[u8]| {
    // Split point, packet fields (CT, FSA, LSA: 5 bytes), reply fields (21 bytes), then
    // sample words up to the noise length byte, then the noise.
    if data.len() < 28 {
        return;
    }
    let (head, rest) = data.split_at(28);
    let split = usize::from(head[0]);
    let samples_len = (usize::from(head[27]) * 2).min(rest.len());
    let (sample_bytes, noise) = rest.split_at(samples_len);

    let at = split.min(noise.len());
    let whole = packets(&[noise]);
    assert_eq!(
        whole,
        packets(&[&noise[..at], &noise[at..]]),
        "chunking at {at}"
    );
    for bytes in &whole.0 {
        assert!(
            Packet::new(bytes).is_some(),
            "a verified packet that does not parse"
        );
    }
    let noise_replies = replies(&[noise]);
    assert_eq!(
        noise_replies,
        replies(&[&noise[..at], &noise[at..]]),
        "chunking at {at}"
    );

    // A packet from the input's fields: quarter-millimetre distances, 1/64° angles.
    let distances_mm: Vec<f64> = sample_bytes
        .chunks_exact(2)
        .map(|w| f64::from(u16::from_le_bytes([w[0], w[1]])) / 4.0)
        .collect();
    let spec = PacketSpec {
        start_of_revolution: head[1] & 1 == 1,
        scan_frequency_hz: f64::from(head[1] >> 1) / 10.0,
        first_angle_deg: f64::from(u16::from_le_bytes([head[2], head[3]])) / 64.0,
        last_angle_deg: f64::from(u16::from_le_bytes([head[4], head[5]])) / 64.0,
        distances_mm: &distances_mm,
    };
    let mut wire = Vec::new();
    encode_packet(&spec, &mut wire).expect("the fields are in range");
    let (found, bad) = packets(&[&wire]);
    assert_eq!(
        (found.len(), bad),
        (1, 0),
        "an encoded packet was not found alone"
    );
    let packet = Packet::new(&found[0]).expect("verified");
    assert_eq!(packet.is_start_of_revolution(), spec.start_of_revolution);
    assert_eq!(packet.sample_count(), distances_mm.len());
    for (i, &d) in distances_mm.iter().enumerate() {
        assert_eq!(packet.distance_mm(i), Some(d));
    }

    // A reply from the input's fields.
    let reply = if head[6] & 1 == 0 {
        let mut serial = [0; 16];
        serial.copy_from_slice(&head[11..27]);
        Reply::DeviceInfo(DeviceInfo {
            model: head[7],
            firmware_major: head[8],
            firmware_minor: head[9],
            hardware: head[10],
            serial,
        })
    } else {
        let status = match head[7] {
            0 => HealthStatus::Ok,
            1 => HealthStatus::Warning,
            2 => HealthStatus::Error,
            other => HealthStatus::Unknown(other),
        };
        Reply::Health(Health {
            status,
            error_code: u16::from_le_bytes([head[8], head[9]]),
        })
    };
    let mut wire = Vec::new();
    reply.encode(&mut wire);
    assert_eq!(replies(&[&wire]), [reply], "{wire:02X?}");
});
