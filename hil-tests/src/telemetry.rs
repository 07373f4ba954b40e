//! The Mega's UART output as timestamped bytes, frames and telemetry batches.
//!
//! Timestamps are simulated CPU cycles (16 MHz) at which the byte left the firmware's
//! USART (simavr's UART output notification). A frame's time is its letter's; a batch's is
//! its first frame's.

use ratf_protocol::channels::{Decoded, Decoder, Frame};
use ratf_protocol::integrity::{Checksum, Crc16, MCU_CHECKSUM_CHANNEL};
use ratf_protocol::mcu::TELEMETRY_FRAMES;
use ratf_protocol::messages::{Faults, QuadratureErrors, Telemetry, WHEEL_COUNT};
use ratf_protocol::settings::SettingsAck;

/// One byte received from the firmware.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RxByte {
    /// Simulated cycle at which it was transmitted.
    pub cycle: u64,
    /// The byte.
    pub byte: u8,
}

/// A complete frame with the cycle of its first byte.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TimedFrame {
    /// Cycle of the channel letter.
    pub cycle: u64,
    /// The frame.
    pub frame: Frame,
}

/// Decode `bytes` into frames with the channels decoder (the original's state machine).
pub fn timed_frames(bytes: &[RxByte]) -> Vec<TimedFrame> {
    let mut decoder = Decoder::new();
    let mut frames = Vec::new();
    let mut letter_cycle = 0;
    for rx in bytes {
        if ratf_protocol::channels::is_channel_letter(rx.byte) {
            letter_cycle = rx.cycle;
        }
        match decoder.push(rx.byte) {
            Decoded::Frame(frame) | Decoded::ShortFrame(frame) => frames.push(TimedFrame {
                cycle: letter_cycle,
                frame,
            }),
            Decoded::Pending => {}
        }
    }
    frames
}

/// Frames up to and including a checksum frame `z` (or the trailing unterminated frames).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TimedBatch {
    /// Cycle of the first frame's letter.
    pub cycle: u64,
    /// The frames, checksum frame included.
    pub frames: Vec<Frame>,
}

impl TimedBatch {
    /// The channel letters in order, e.g. `b"ghijksqxyz"`.
    pub fn letters(&self) -> Vec<u8> {
        self.frames.iter().map(Frame::channel).collect()
    }

    /// True when this is a complete telemetry batch `g h i j k s q x y z`.
    pub fn is_telemetry(&self) -> bool {
        self.letters() == b"ghijksqxyz"
    }
}

/// Group frames into batches, each closed by a `z` frame. Frames after the last `z` are
/// dropped (a batch still being transmitted).
pub fn batches(frames: &[TimedFrame]) -> Vec<TimedBatch> {
    let mut out = Vec::new();
    let mut current: Option<TimedBatch> = None;
    for tf in frames {
        let batch = current.get_or_insert_with(|| TimedBatch {
            cycle: tf.cycle,
            frames: Vec::new(),
        });
        batch.frames.push(tf.frame);
        if tf.frame.channel() == MCU_CHECKSUM_CHANNEL {
            out.extend(current.take());
        }
    }
    out
}

/// The typed content of one telemetry batch.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TelemetryBatch {
    /// Cumulative encoder ticks per wheel (`g h i j`).
    pub ticks: [i32; WHEEL_COUNT],
    /// Measured control period, µs (`k`).
    pub period_us: u32,
    /// Switch pressed (`s` = 0).
    pub switch_pressed: bool,
    /// Invalid quadrature transitions per wheel (`q`).
    pub quadrature_errors: [u8; WHEEL_COUNT],
    /// Fault counters (`x`).
    pub faults: Faults,
    /// The controller settings' acknowledgement (`y`).
    pub settings_ack: SettingsAck,
}

impl TelemetryBatch {
    /// Parse a `g h i j k s q x y z` batch; an error names the first unexpected frame.
    pub fn parse(batch: &TimedBatch) -> Result<Self, String> {
        if !batch.is_telemetry() {
            return Err(format!(
                "not a telemetry batch: letters {:?}",
                String::from_utf8_lossy(&batch.letters())
            ));
        }
        let mut parsed = Self {
            ticks: [0; WHEEL_COUNT],
            period_us: 0,
            switch_pressed: false,
            quadrature_errors: [0; WHEEL_COUNT],
            faults: Faults::default(),
            settings_ack: SettingsAck::default(),
        };
        for frame in &batch.frames[..TELEMETRY_FRAMES] {
            match Telemetry::from_frame(*frame) {
                Ok(Telemetry::Ticks { wheel, total }) => parsed.ticks[wheel.index()] = total,
                Ok(Telemetry::LoopPeriod { period_us }) => parsed.period_us = period_us,
                Ok(Telemetry::Switch { pressed }) => parsed.switch_pressed = pressed,
                Ok(Telemetry::QuadratureErrors(QuadratureErrors(q))) => {
                    parsed.quadrature_errors = q;
                }
                Ok(Telemetry::Faults(faults)) => parsed.faults = faults,
                Ok(Telemetry::SettingsAck(ack)) => parsed.settings_ack = ack,
                Ok(other) => return Err(format!("unexpected message {other:?} in a batch")),
                Err(e) => return Err(format!("bad frame {frame:?}: {e}")),
            }
        }
        Ok(parsed)
    }
}

/// The batch's checksum frame: sequence number and whether count and CRC match its frames
/// (protocol `integrity`, checked independently of the receiver's mode switch). `None` when
/// the batch does not end with a `z` frame.
pub fn checksum(batch: &TimedBatch) -> Option<(u8, bool)> {
    let (last, frames) = batch.frames.split_last()?;
    if last.channel() != MCU_CHECKSUM_CHANNEL {
        return None;
    }
    let claimed = Checksum::from_value(last.value());
    let crc = frames
        .iter()
        .fold(Crc16::new(), |crc, f| crc.update(&f.encode()));
    let ok = usize::from(claimed.count) == frames.len()
        && Checksum::seal(crc, claimed.seq, claimed.count) == claimed;
    Some((claimed.seq, ok))
}

#[cfg(test)]
mod tests {
    use super::*;
    use ratf_protocol::mcu::{Mcu, McuConfig, TickInputs};

    fn timed(bytes: &[u8], start: u64) -> Vec<RxByte> {
        bytes
            .iter()
            .enumerate()
            .map(|(i, &byte)| RxByte {
                cycle: start + 100 * i as u64,
                byte,
            })
            .collect()
    }

    #[test]
    fn batches_of_the_reference_mcu_parse() {
        let mut mcu = Mcu::new(McuConfig::default());
        let mut rx = timed(mcu.boot().as_bytes(), 0);
        let inputs = TickInputs {
            encoder_deltas: [3, -2, 0, 7],
            switch_pressed: true,
            ..TickInputs::default()
        };
        rx.extend(timed(
            mcu.control_tick(0, &inputs).telemetry.as_bytes(),
            10_000,
        ));
        let frames = timed_frames(&rx);
        let batches = batches(&frames);
        assert_eq!(batches.len(), 2);
        assert_eq!(batches[0].letters(), b"rz");
        assert_eq!(batches[1].cycle, 10_000);
        let t = TelemetryBatch::parse(&batches[1]).unwrap();
        assert_eq!(t.ticks, [3, -2, 0, 7]);
        assert_eq!(t.period_us, 20_000);
        assert!(t.switch_pressed);
        assert!(TelemetryBatch::parse(&batches[0]).is_err());
        assert_eq!(checksum(&batches[0]), Some((0, true)));
        assert_eq!(checksum(&batches[1]), Some((1, true)));
        let mut corrupt = batches[1].clone();
        corrupt.frames[0] = Frame::new(b'g', 4).unwrap();
        assert_eq!(checksum(&corrupt), Some((1, false)));
    }

    #[test]
    fn unterminated_batch_is_dropped() {
        let frames = timed_frames(&timed(b"g00000001h0000", 0));
        assert_eq!(frames.len(), 1);
        assert!(batches(&frames).is_empty());
    }
}
