//! A YDLIDAR X4 on the far side of a pseudo-terminal, built on the simulator's packet
//! encoder: silent until its start command `A5 60`, then the response descriptor and one
//! revolution every 1/7 s (360 samples, 40 per packet), trickled over the revolution (6 bytes
//! a millisecond), so the host reads packets in pieces; quiet again at `A5 65`, or when told
//! to fall silent with its port open ([`FakeX4::fall_silent`]).
//! It can damage its stream: a bad check code in every other revolution, a stream that
//! starts in the middle of a packet, or no answer at all. Unplugged, it loses power: silent
//! again until the next start command. It answers the device-information and health
//! requests (an X4, model 6, healthy) unless told to keep quiet, as some clones do, or to
//! report a health error.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use ratf_core::drivers::x4::encoder::RevolutionEncoder;
use ratf_core::drivers::x4::info::{DeviceInfo, Health, HealthStatus, MODEL_X4, Reply, Request};
use ratf_core::drivers::x4::{Command, CommandDecoder, RESPONSE_HEADER, Received};

use super::pty::Pty;

/// Samples per revolution (one a degree).
pub(crate) const SAMPLES: usize = 360;
/// Samples per data packet.
pub(crate) const PER_PACKET: usize = 40;
/// A revolution's period (7 Hz).
const REVOLUTION: Duration = Duration::from_micros(142_857);
/// Bytes written per millisecond: 6, so a revolution's 822 bytes take 137 of its 143 ms, as
/// a real X4 sends each packet as soon as its samples are taken (40 samples at 5 kHz, 8 ms)
/// rather than in one burst (the line itself carries 13 bytes a millisecond at 128 000
/// baud, 8N1). A burst and a pause of 80 ms would look like a stream that stopped.
const BYTES_PER_MS: usize = 6;
/// Bytes of the start-of-revolution packet (header and one sample).
const ZERO_PACKET_LEN: usize = 12;
/// Bytes of a full data packet.
const DATA_PACKET_LEN: usize = 10 + 2 * PER_PACKET;

/// How the X4 misbehaves.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Fault {
    /// The second data packet of every odd revolution has a bad check code.
    CorruptOddRevolutions,
    /// After the start command, no response descriptor: the stream begins in the middle
    /// of a data packet.
    StartsMidPacket,
    /// Never sends a byte.
    Silent,
    /// Scans, but ignores the device-information and health requests (as some clones do).
    NoIdentity,
    /// Scans, and its health is an error with code [`HEALTH_ERROR_CODE`].
    HealthError,
}

/// The error code of [`Fault::HealthError`].
pub(crate) const HEALTH_ERROR_CODE: u16 = 0x0102;

/// What the emulated X4 says it is.
pub(crate) const INFO: DeviceInfo = DeviceInfo {
    model: MODEL_X4,
    firmware_major: 1,
    firmware_minor: 7,
    hardware: 1,
    serial: [2, 0, 1, 7, 0, 1, 0, 1, 0, 0, 0, 0, 0, 0, 4, 2],
};

/// The emulated X4: see the module documentation.
pub(crate) struct FakeX4 {
    /// Its port.
    pub(crate) pty: Pty,
    fault: Fault,
    decoder: CommandDecoder,
    /// Every command the host sent, with its arrival.
    pub(crate) commands: Vec<(Instant, Command)>,
    /// Every command and request the host sent, in order.
    pub(crate) received: Vec<Received>,
    streaming: bool,
    revolutions: u32,
    next_revolution: Instant,
    outbox: VecDeque<u8>,
    next_write: Instant,
}

/// The distance of sample `k`, mm: 0.8 m to 1.9 m around the revolution.
pub(crate) fn distance_mm(k: usize) -> f64 {
    800.0 + 3.0 * k as f64
}

impl FakeX4 {
    /// An X4 behind `pty` with `fault`.
    pub(crate) fn new(pty: Pty, fault: Fault) -> Self {
        let now = Instant::now();
        Self {
            pty,
            fault,
            decoder: CommandDecoder::new(),
            commands: Vec::new(),
            received: Vec::new(),
            streaming: false,
            revolutions: 0,
            next_revolution: now,
            outbox: VecDeque::new(),
            next_write: now,
        }
    }

    /// Start commands received.
    pub(crate) fn starts(&self) -> usize {
        self.commands
            .iter()
            .filter(|(_, c)| *c == Command::StartScan)
            .count()
    }

    /// Stop sending for good with the port open, as an X4 whose motor stalled or whose
    /// board hung: a start command wakes it again.
    pub(crate) fn fall_silent(&mut self) {
        self.streaming = false;
        self.outbox.clear();
    }

    /// Be the X4 until `until`.
    pub(crate) fn service(&mut self, until: Instant) {
        loop {
            let now = Instant::now();
            if now >= until {
                return;
            }
            if !self.pty.connected() {
                // Unplugged (or the port closed): the X4 loses power and comes back silent.
                self.streaming = false;
                self.outbox.clear();
            }
            let mut next = until;
            if self.streaming {
                next = next.min(self.next_revolution);
            }
            if !self.outbox.is_empty() {
                next = next.min(self.next_write);
            }
            let bytes = self.pty.read_until(next);
            let now = Instant::now();
            let mut received = Vec::new();
            self.decoder.feed_all(&bytes, |r| received.push(r));
            for r in received {
                self.received.push(r);
                match r {
                    Received::Command(command) => {
                        self.commands.push((now, command));
                        self.command(command, now);
                    }
                    Received::Request(request) => self.answer(request),
                }
            }
            if self.streaming && now >= self.next_revolution {
                self.revolution();
                self.next_revolution += REVOLUTION;
            }
            if !self.outbox.is_empty() && now >= self.next_write {
                let n = BYTES_PER_MS.min(self.outbox.len());
                let chunk: Vec<u8> = self.outbox.drain(..n).collect();
                self.pty.write(&chunk);
                self.next_write = now + Duration::from_millis(1);
            }
        }
    }

    fn command(&mut self, command: Command, now: Instant) {
        match command {
            Command::StartScan if self.fault != Fault::Silent => {
                if self.fault == Fault::StartsMidPacket {
                    let mut first = Vec::new();
                    self.encode(&mut first);
                    // Half-way into the first data packet.
                    let cut = ZERO_PACKET_LEN + DATA_PACKET_LEN / 2;
                    self.outbox.extend(&first[cut..]);
                } else {
                    self.outbox.extend(RESPONSE_HEADER);
                }
                self.streaming = true;
                self.next_revolution = now;
            }
            Command::StopScan => {
                self.streaming = false;
                self.outbox.clear();
            }
            Command::StartScan | Command::SoftRestart => {}
        }
    }

    fn answer(&mut self, request: Request) {
        let reply = match (request, self.fault) {
            (_, Fault::Silent | Fault::NoIdentity) => return,
            (Request::DeviceInfo, _) => Reply::DeviceInfo(INFO),
            (Request::Health, Fault::HealthError) => Reply::Health(Health {
                status: HealthStatus::Error,
                error_code: HEALTH_ERROR_CODE,
            }),
            (Request::Health, _) => Reply::Health(Health {
                status: HealthStatus::Ok,
                error_code: 0,
            }),
        };
        let mut bytes = Vec::new();
        reply.encode(&mut bytes);
        self.outbox.extend(bytes);
    }

    fn encode(&self, out: &mut Vec<u8>) {
        let distances: Vec<f64> = (0..SAMPLES).map(distance_mm).collect();
        let encoder = RevolutionEncoder {
            samples_per_packet: PER_PACKET as u8,
            scan_frequency_hz: 7.0,
        };
        encoder
            .encode_revolution(0.0, 1.0, &distances, out)
            .expect("a valid revolution");
    }

    fn revolution(&mut self) {
        let mut bytes = Vec::new();
        self.encode(&mut bytes);
        if self.fault == Fault::CorruptOddRevolutions && self.revolutions % 2 == 1 {
            // A distance byte of the second data packet: its check code no longer matches.
            bytes[ZERO_PACKET_LEN + DATA_PACKET_LEN + 20] ^= 0x10;
        }
        self.revolutions += 1;
        self.outbox.extend(bytes);
    }
}
