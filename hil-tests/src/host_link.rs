//! The host's side of the link: command batches encoded exactly as the Pi sends them
//! (channels frames closed by a `Z` checksum frame, protocol `integrity`).

use ratf_protocol::channels::Frame;
use ratf_protocol::integrity::{BatchWriter, HOST_CHECKSUM_CHANNEL};
use ratf_protocol::messages::{Command, WHEEL_COUNT, Wheel};

/// Encodes host command batches with consecutive sequence numbers.
#[derive(Clone, Debug)]
pub struct HostLink {
    writer: BatchWriter,
}

impl HostLink {
    /// A host that closes every batch with a checksum frame (`with_checksums`), or one that
    /// speaks the original protocol (no checksums).
    pub fn new(with_checksums: bool) -> Self {
        Self {
            writer: BatchWriter::new(HOST_CHECKSUM_CHANNEL, with_checksums),
        }
    }

    /// The bytes of one batch carrying `commands`.
    pub fn batch(&mut self, commands: &[Command]) -> Vec<u8> {
        let frames: Vec<Frame> = commands.iter().map(Command::to_frame).collect();
        let mut bytes = vec![0u8; self.writer.batch_len(frames.len())];
        // The buffer is sized by `batch_len`, so the write cannot run short; an empty
        // result would make the test's assertions fail loudly anyway.
        let n = self.writer.write_batch(&frames, &mut bytes).unwrap_or(0);
        bytes.truncate(n);
        bytes
    }
}

/// `G H I J` commands setting every wheel's speed reference, wheel rad/s.
pub fn wheel_speeds(speeds_rad_s: [f32; WHEEL_COUNT]) -> Vec<Command> {
    Wheel::ALL
        .iter()
        .zip(speeds_rad_s)
        .map(|(&wheel, speed_rad_s)| Command::WheelSpeed { wheel, speed_rad_s })
        .collect()
}

/// Send one `G H I J` batch at `speed_rad_s` for every wheel each control period, for
/// `periods` periods, from a fresh host link, and return the shield's signed PWMs then.
pub fn command_all_wheels(hil: &mut crate::sim::Hil, speed_rad_s: f32, periods: u32) -> [i16; 4] {
    let mut host = HostLink::new(true);
    for _ in 0..periods {
        hil.send(&host.batch(&wheel_speeds([speed_rad_s; 4])));
        hil.run_for_ms(20);
    }
    crate::shield::signed_pwms(&hil.shield())
}

#[cfg(test)]
mod tests {
    use super::*;
    use ratf_protocol::mcu::{Mcu, McuConfig, TickInputs};

    #[test]
    fn batches_are_accepted_by_the_reference_mcu() {
        let mut link = HostLink::new(true);
        let mut mcu = Mcu::new(McuConfig::default());
        let bytes = link.batch(&wheel_speeds([1.0, 2.0, 3.0, 4.0]));
        assert_eq!(bytes.len(), 45);
        assert_eq!(bytes[36], b'Z');
        mcu.receive(&bytes, 0);
        assert!(!mcu.timed_out());
        let out = mcu.control_tick(0, &TickInputs::default());
        assert!(out.actuation.pwm.iter().all(|&p| p > 0));
    }
}
