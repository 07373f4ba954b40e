//! The host side of the Mega link (original-system.md §3.1), fixed per §10.1–10.4.
//!
//! Receive: [`MegaLink::feed`] takes the bytes received from the Mega and their receive
//! time, decodes them with [`BatchReceiver`] (the Mega's checksum channel `z`), and turns
//! each telemetry batch `g h i j k s q x` into one [`WheelTelemetry`].
//!
//! - **Strict mode** (the Mega sends checksums): frames arrive only in verified batches; a
//!   batch becomes a [`WheelTelemetry`] once it is verified, whole. A corrupted batch is
//!   dropped and counted by the receiver ([`MegaLinkStats::link`]).
//! - **Compatible mode** (an original Mega, which sends only `g h i j k s` and no
//!   checksum; also our Mega before its first checksum frame): frames arrive one by one; `g`
//!   starts a batch and `s` completes it. The `q` and `x` diagnostics that our Mega sends
//!   after `s` are kept and reported with the *next* batch in this mode.
//!
//! A batch that lacks any of `g h i j k s` when it completes (a frame was lost in
//! compatible mode, or the stream started mid-batch) is dropped and counted in
//! [`MegaLinkStats::incomplete_batches`].
//!
//! `r` (the Mega booted) is reported as [`MegaEvent::Reset`]: the Mega's cumulative tick
//! totals restart from zero, so the next batch carries no deltas. A partial batch is
//! dropped. This is a resynchronisation point, not just a state wipe (§10.1).
//!
//! Send: [`MegaLink::encode_references`] writes `G H I J L U` and [`MegaLink::encode_pwm`]
//! writes `K K K K L`, each closed by a checksum frame `Z` ([`BatchWriter`]). An original
//! Mega ignores `Z` (original-system.md §2.6), so checksums are safe to send to it. The host
//! sends references on its own timer; [`reference_is_stale`] is the host watchdog, on the
//! *age* of the last reference (fixing §10.2, which compared the gap between the last two).

use ratf_protocol::channels::{FRAME_LEN, Frame};
use ratf_protocol::integrity::{
    BatchReceiver, BatchWriter, HOST_CHECKSUM_CHANNEL, LinkStats, MCU_CHECKSUM_CHANNEL, Mode,
};
use ratf_protocol::mcu::McuConfig;
use ratf_protocol::messages::{Command, Faults, QuadratureErrors, Telemetry, WHEEL_COUNT, Wheel};
use ratf_protocol::settings::SettingsAck;

/// Largest Mega batch buffered, frames: our Mega sends 8 (`g h i j k s q x`); twice that
/// leaves room without letting a broken stream hold much.
const RX_BATCH_CAPACITY: usize = 16;

/// Frames of one reference batch before its checksum frame: `G H I J L U`
/// ([`MegaLink::encode_references`]).
pub const REFERENCE_BATCH_FRAMES: usize = WHEEL_COUNT + 2;

/// The host watchdog's default timeout, µs: 200 ms, the original host driver's constant
/// (original-system.md §3.1). The Mega's own watchdog (100 ms after the last `G`/`K`) stops
/// the motors if the host goes silent; this one stops *sending motion* when the planner
/// goes silent.
pub const DEFAULT_REFERENCE_TIMEOUT_US: u64 = 200_000;

/// One telemetry batch from the Mega.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct WheelTelemetry {
    /// Cumulative encoder ticks since the Mega booted, per wheel (motor index order),
    /// wrapping.
    pub totals: [i32; WHEEL_COUNT],
    /// Ticks since the previous batch received (wrapping difference of the totals); `None`
    /// for the first batch after start-up or a Mega reset. Spans more than one control
    /// period when batches were lost.
    pub deltas_ticks: Option<[i32; WHEEL_COUNT]>,
    /// The Mega's measured control period (`k`), µs.
    pub period_us: u32,
    /// The box switch is pressed.
    pub switch_pressed: bool,
    /// Invalid quadrature transitions per wheel (`q`), the latest received; `None` until
    /// the Mega has sent one (an original Mega never does).
    pub quadrature_errors: Option<QuadratureErrors>,
    /// The Mega's fault counters (`x`), the latest received; `None` as above.
    pub faults: Option<Faults>,
    /// The Mega's acknowledgement of the controller settings (`y`), the latest received;
    /// `None` as above (and in recordings made before the channel existed).
    #[serde(default)]
    pub settings_ack: Option<SettingsAck>,
    /// True if the batch was verified by its checksum frame (strict mode).
    pub verified: bool,
    /// Receive time of the bytes that completed the batch, µs (caller's monotonic clock).
    pub received_at_us: u64,
    /// Estimated time the Mega sampled the encoders for this batch, µs (caller's clock): the
    /// receive time less the batch's time on the wire (its bytes at the link's baud rate, 10
    /// bits each) and the firmware's measured delay from its tick to the first byte
    /// ([`MegaLinkConfig::telemetry_latency_us`]). The odometry increment ends here.
    pub sampled_at_us: u64,
}

/// What the link reports.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MegaEvent {
    /// A complete telemetry batch.
    Telemetry(WheelTelemetry),
    /// The Mega (re)booted (`r`): its tick totals restart from zero.
    Reset {
        /// Receive time of the `r` frame's bytes, µs.
        received_at_us: u64,
    },
}

/// Link counters.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MegaLinkStats {
    /// The receiver's counters: corrupt, out-of-sequence and overflowed batches, aborted
    /// frames.
    pub link: LinkStats,
    /// Compatible until the Mega's first valid checksum frame, strict after.
    pub mode: Mode,
    /// Telemetry batches reported.
    pub batches: u32,
    /// Batches dropped because a frame of `g h i j k s` was missing.
    pub incomplete_batches: u32,
    /// Frames that are not valid telemetry (unknown letter, `s` not 0 or 1).
    pub bad_messages: u32,
    /// `r` frames received.
    pub resets: u32,
}

/// Why a command batch was not encoded.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum EncodeError {
    /// A wheel speed reference is NaN or infinite; the Mega would reject it.
    #[error("wheel {wheel} speed reference {value} rad/s is not finite")]
    NotFinite {
        /// Wheel index (0 back-right, 1 back-left, 2 front-right, 3 front-left).
        wheel: usize,
        /// The offending value.
        value: f32,
    },
}

/// Telemetry fields collected so far in the current batch.
#[derive(Clone, Copy, Debug, Default)]
struct Partial {
    started: bool,
    /// Frames received since the batch started (any letter), for its time on the wire.
    frames: u32,
    totals: [Option<i32>; WHEEL_COUNT],
    period_us: Option<u32>,
    switch_pressed: Option<bool>,
}

/// Turns delivered frames into events; separate from the receiver so both can be borrowed
/// at once.
#[derive(Clone, Debug, Default)]
struct Assembler {
    partial: Partial,
    previous_totals: Option<[i32; WHEEL_COUNT]>,
    quadrature_errors: Option<QuadratureErrors>,
    faults: Option<Faults>,
    settings_ack: Option<SettingsAck>,
    batches: u32,
    incomplete_batches: u32,
    bad_messages: u32,
    resets: u32,
}

#[cfg(test)]
impl WheelTelemetry {
    /// A verified batch of wheels at `totals` with the switch at `switch_pressed`, sampled and
    /// received at `at_us`, no deltas yet, at the default 20 ms period (for tests).
    pub(crate) fn for_test(totals: [i32; WHEEL_COUNT], switch_pressed: bool, at_us: u64) -> Self {
        Self {
            totals,
            deltas_ticks: None,
            period_us: 20_000,
            switch_pressed,
            quadrature_errors: None,
            faults: None,
            settings_ack: None,
            verified: true,
            received_at_us: at_us,
            sampled_at_us: at_us,
        }
    }
}

impl Assembler {
    fn frame(
        &mut self,
        frame: Frame,
        strict: bool,
        now_us: u64,
        link: &MegaLinkConfig,
        out: &mut impl FnMut(MegaEvent),
    ) {
        self.partial.frames += 1;
        let message = match Telemetry::from_frame(frame) {
            Ok(message) => message,
            Err(_) => {
                self.bad_messages = self.bad_messages.wrapping_add(1);
                return;
            }
        };
        match message {
            Telemetry::Reset => {
                self.drop_partial();
                self.previous_totals = None;
                self.resets = self.resets.wrapping_add(1);
                out(MegaEvent::Reset {
                    received_at_us: now_us,
                });
            }
            Telemetry::Ticks { wheel, total } => {
                if wheel == Wheel::BackRight {
                    self.drop_partial();
                }
                self.partial.started = true;
                self.partial.totals[wheel.index()] = Some(total);
            }
            Telemetry::LoopPeriod { period_us } => {
                self.partial.started = true;
                self.partial.period_us = Some(period_us);
            }
            Telemetry::Switch { pressed } => {
                self.partial.started = true;
                self.partial.switch_pressed = Some(pressed);
                if !strict {
                    self.complete(false, 0, now_us, link, out);
                }
            }
            Telemetry::QuadratureErrors(q) => self.quadrature_errors = Some(q),
            Telemetry::Faults(f) => self.faults = Some(f),
            Telemetry::SettingsAck(ack) => self.settings_ack = Some(ack),
        }
    }

    /// A partial batch that will never complete.
    fn drop_partial(&mut self) {
        if self.partial.started {
            self.incomplete_batches = self.incomplete_batches.wrapping_add(1);
        }
        self.partial = Partial {
            frames: 1,
            ..Partial::default()
        };
    }

    /// The current batch is over: report it if it has every field. `extra_frames`: frames
    /// of the batch not delivered as telemetry (its checksum frame).
    fn complete(
        &mut self,
        verified: bool,
        extra_frames: u32,
        now_us: u64,
        link: &MegaLinkConfig,
        out: &mut impl FnMut(MegaEvent),
    ) {
        let partial = core::mem::take(&mut self.partial);
        if !partial.started {
            return;
        }
        let (Some(period_us), Some(switch_pressed)) = (partial.period_us, partial.switch_pressed)
        else {
            self.incomplete_batches = self.incomplete_batches.wrapping_add(1);
            return;
        };
        let mut totals = [0; WHEEL_COUNT];
        for (total, got) in totals.iter_mut().zip(partial.totals) {
            let Some(got) = got else {
                self.incomplete_batches = self.incomplete_batches.wrapping_add(1);
                return;
            };
            *total = got;
        }
        let deltas_ticks = self.previous_totals.map(|previous| {
            let mut deltas = [0; WHEEL_COUNT];
            for k in 0..WHEEL_COUNT {
                deltas[k] = totals[k].wrapping_sub(previous[k]);
            }
            deltas
        });
        self.previous_totals = Some(totals);
        self.batches = self.batches.wrapping_add(1);
        let bytes = u64::from(partial.frames + extra_frames) * FRAME_LEN as u64;
        let on_wire_us = bytes * 10 * 1_000_000 / u64::from(link.baud.max(1));
        let sampled_at_us = now_us
            .saturating_sub(on_wire_us)
            .saturating_sub(u64::from(link.telemetry_latency_us));
        out(MegaEvent::Telemetry(WheelTelemetry {
            totals,
            deltas_ticks,
            period_us,
            switch_pressed,
            quadrature_errors: self.quadrature_errors,
            faults: self.faults,
            settings_ack: self.settings_ack,
            verified,
            received_at_us: now_us,
            sampled_at_us,
        }));
    }
}

/// Settings of the host side of the link.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MegaLinkConfig {
    /// Close each command batch with a checksum frame `Z`. On by default (an original Mega
    /// ignores it); off sends exactly the original protocol.
    pub send_checksums: bool,
    /// The serial line's baud rate (115 200).
    pub baud: u32,
    /// The firmware's delay from its control tick to the first telemetry byte, µs (see
    /// `config::MegaConfig::telemetry_latency_us`).
    pub telemetry_latency_us: u32,
}

impl Default for MegaLinkConfig {
    fn default() -> Self {
        Self {
            send_checksums: true,
            baud: 115_200,
            telemetry_latency_us: 2_080,
        }
    }
}

/// The host side of the Mega link: see the module documentation.
#[derive(Clone, Debug)]
pub struct MegaLink {
    config: MegaLinkConfig,
    receiver: BatchReceiver<RX_BATCH_CAPACITY>,
    writer: BatchWriter,
    assembler: Assembler,
}

impl Default for MegaLink {
    fn default() -> Self {
        Self::new(MegaLinkConfig::default())
    }
}

impl MegaLink {
    /// A link in compatible mode that has received nothing.
    pub fn new(config: MegaLinkConfig) -> Self {
        Self {
            config,
            receiver: BatchReceiver::new(MCU_CHECKSUM_CHANNEL),
            writer: BatchWriter::new(HOST_CHECKSUM_CHANNEL, config.send_checksums),
            assembler: Assembler::default(),
        }
    }

    /// Forget any partial batch and return to compatible mode, e.g. after re-opening the
    /// port (which resets the Mega). Counters are kept.
    pub fn reset(&mut self) {
        self.receiver.reset();
        self.assembler.partial = Partial::default();
        self.assembler.previous_totals = None;
        self.assembler.settings_ack = None;
    }

    /// Feed bytes received from the Mega at `now_us` (any chunking); `on_event` gets every
    /// completed batch and every reset, in order.
    pub fn feed(&mut self, bytes: &[u8], now_us: u64, mut on_event: impl FnMut(MegaEvent)) {
        let Self {
            config,
            receiver,
            assembler,
            ..
        } = self;
        // One byte at a time: in strict mode, the frames released by one byte (the last of
        // a checksum frame) are exactly one verified batch.
        for byte in bytes {
            let strict = receiver.mode() == Mode::Strict;
            let mut delivered = false;
            receiver.feed(core::slice::from_ref(byte), |frame| {
                delivered = true;
                assembler.frame(frame, strict, now_us, config, &mut on_event);
            });
            if strict && delivered {
                assembler.complete(true, 1, now_us, config, &mut on_event);
            }
        }
    }

    /// Counters since construction.
    pub fn stats(&self) -> MegaLinkStats {
        let a = &self.assembler;
        MegaLinkStats {
            link: self.receiver.stats(),
            mode: self.receiver.mode(),
            batches: a.batches,
            incomplete_batches: a.incomplete_batches,
            bad_messages: a.bad_messages,
            resets: a.resets,
        }
    }

    /// The bytes of one reference batch: `G H I J` (wheel speed references, wheel rad/s,
    /// motor index order: back-right, back-left, front-right, front-left), `L` (solenoid),
    /// `U` (the Mega's stop on the switch armed or not,
    /// [`ratf_protocol::messages::Command::StopOnSwitch`]) and the checksum frame.
    pub fn encode_references(
        &mut self,
        wheel_speeds_rad_s: [f32; WHEEL_COUNT],
        solenoid_on: bool,
        stop_on_switch: bool,
    ) -> Result<Vec<u8>, EncodeError> {
        let mut commands = [Command::Solenoid { on: solenoid_on }; REFERENCE_BATCH_FRAMES];
        commands[WHEEL_COUNT + 1] = Command::StopOnSwitch {
            armed: stop_on_switch,
        };
        for (k, &speed_rad_s) in wheel_speeds_rad_s.iter().enumerate() {
            if !speed_rad_s.is_finite() {
                return Err(EncodeError::NotFinite {
                    wheel: k,
                    value: speed_rad_s,
                });
            }
            commands[k] = Command::WheelSpeed {
                wheel: Wheel::ALL[k],
                speed_rad_s,
            };
        }
        Ok(self.write(&commands))
    }

    /// The bytes of one open-loop batch: four `K` (signed PWM per motor, motor index order;
    /// the Mega clamps the magnitude to 255), `L` (solenoid), and the checksum frame. Used
    /// for motor identification, as the original's tune node.
    pub fn encode_pwm(&mut self, pwm: [i16; WHEEL_COUNT], solenoid_on: bool) -> Vec<u8> {
        let mut commands = [Command::Solenoid { on: solenoid_on }; WHEEL_COUNT + 1];
        for (k, &pwm) in pwm.iter().enumerate() {
            commands[k] = Command::MotorPwm {
                wheel: Wheel::ALL[k],
                pwm,
            };
        }
        self.write(&commands)
    }

    /// The bytes of one settings batch: `M`..`T` with `config`'s controller settings
    /// (gains, feed-forward, dead zone, battery voltage, voltage limit, ticks per wheel
    /// revolution; `ratf_protocol::settings`) and the checksum frame. Our Mega applies them
    /// and acknowledges them on `y`; an original Mega ignores them.
    pub fn encode_settings(&mut self, config: &McuConfig) -> Vec<u8> {
        self.write(&config.setting_commands())
    }

    fn write<const N: usize>(&mut self, commands: &[Command; N]) -> Vec<u8> {
        let frames = commands.map(|c| c.to_frame());
        let mut out = vec![0; (frames.len() + 1) * FRAME_LEN];
        // The buffer holds the batch and its checksum frame.
        let n = self.writer.write_batch(&frames, &mut out).unwrap_or(0);
        out.truncate(n);
        out
    }
}

/// Age of the last wheel reference at `now_us`, µs; `None` if there has been none, or if
/// the clock reads earlier than that reference (a clock fault).
pub fn reference_age_us(last_reference_us: Option<u64>, now_us: u64) -> Option<u64> {
    last_reference_us.and_then(|last| now_us.checked_sub(last))
}

/// The host watchdog: true when the last reference is older than `timeout_us` at `now_us`,
/// or there is none, or the clock went backwards (fail-safe: send zero speeds).
pub fn reference_is_stale(last_reference_us: Option<u64>, now_us: u64, timeout_us: u64) -> bool {
    reference_age_us(last_reference_us, now_us).is_none_or(|age| age > timeout_us)
}

/// The wheel speeds to send: `wheel_speeds_rad_s`, or zeros when the reference is stale.
pub fn guarded_references(
    wheel_speeds_rad_s: [f32; WHEEL_COUNT],
    last_reference_us: Option<u64>,
    now_us: u64,
    timeout_us: u64,
) -> [f32; WHEEL_COUNT] {
    if reference_is_stale(last_reference_us, now_us, timeout_us) {
        [0.0; WHEEL_COUNT]
    } else {
        wheel_speeds_rad_s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use ratf_protocol::mcu::{Mcu, McuConfig, TickInputs};

    fn collect(link: &mut MegaLink, bytes: &[u8], now_us: u64) -> Vec<MegaEvent> {
        let mut events = Vec::new();
        link.feed(bytes, now_us, |e| events.push(e));
        events
    }

    fn telemetry(events: &[MegaEvent]) -> Vec<WheelTelemetry> {
        events
            .iter()
            .filter_map(|e| match e {
                MegaEvent::Telemetry(t) => Some(*t),
                MegaEvent::Reset { .. } => None,
            })
            .collect()
    }

    fn frames(list: &[(u8, u32)]) -> Vec<u8> {
        list.iter()
            .flat_map(|&(c, v)| Frame::new(c, v).unwrap().encode())
            .collect()
    }

    /// One batch as an original Mega sends it: `g h i j k s`, no checksum.
    fn original_batch(totals: [i32; 4], period_us: u32, switch_level: u32) -> Vec<u8> {
        frames(&[
            (b'g', totals[0] as u32),
            (b'h', totals[1] as u32),
            (b'i', totals[2] as u32),
            (b'j', totals[3] as u32),
            (b'k', period_us),
            (b's', switch_level),
        ])
    }

    #[test]
    fn the_stop_on_the_switch_reaches_the_mega_armed_and_disarmed() {
        let mut mcu = Mcu::new(McuConfig::default());
        let mut link = MegaLink::default();
        let pressed = TickInputs {
            switch_pressed: true,
            ..TickInputs::default()
        };
        let bytes = link.encode_references([5.0; 4], true, true).unwrap();
        mcu.receive(&bytes, 1_000);
        mcu.control_tick(20_000, &pressed);
        assert!(mcu.stopped_on_switch());
        let bytes = link.encode_references([5.0; 4], true, false).unwrap();
        mcu.receive(&bytes, 21_000);
        assert!(!mcu.stopped_on_switch());
    }

    #[test]
    fn round_trip_with_the_mcu() {
        let mut mcu = Mcu::new(McuConfig::default());
        let mut link = MegaLink::default();
        let boot = collect(&mut link, mcu.boot().as_bytes(), 5);
        assert_eq!(boot, [MegaEvent::Reset { received_at_us: 5 }]);

        let mut expected_totals = [0i32; 4];
        let deltas: [i16; 4] = [12, -7, 3, -1];
        for tick in 1..=5u32 {
            let now_us = tick * 20_000;
            let bytes = link
                .encode_references([5.0, -5.0, 5.0, -5.0], true, false)
                .unwrap();
            assert_eq!(bytes.len(), 7 * FRAME_LEN);
            mcu.receive(&bytes, now_us - 1_000);
            assert!(mcu.solenoid_on());
            let inputs = TickInputs {
                encoder_deltas: deltas,
                switch_pressed: tick % 2 == 0,
                quadrature_errors: [tick as u8, 0, 2, 3],
                i2c_faults: 7,
                serial_bytes_dropped: 2,
            };
            let out = mcu.control_tick(now_us, &inputs);
            // The Mega obeyed the references: forward on wheels 0 and 2, backward on 1, 3.
            assert!(out.actuation.pwm[0] > 0 && out.actuation.pwm[2] > 0);
            assert!(out.actuation.pwm[1] < 0 && out.actuation.pwm[3] < 0);
            for (total, d) in expected_totals.iter_mut().zip(deltas) {
                *total += i32::from(d);
            }
            let events = collect(&mut link, out.telemetry.as_bytes(), u64::from(now_us) + 3);
            let t = telemetry(&events);
            assert_eq!(t.len(), 1, "tick {tick}");
            let t = t[0];
            assert_eq!(t.totals, expected_totals);
            assert_eq!(
                t.deltas_ticks,
                (tick > 1).then(|| deltas.map(i32::from)),
                "tick {tick}"
            );
            assert_eq!(t.period_us, 20_000);
            assert_eq!(t.switch_pressed, tick % 2 == 0);
            assert_eq!(
                t.quadrature_errors,
                Some(QuadratureErrors([tick as u8, 0, 2, 3]))
            );
            assert_eq!(t.faults.map(|f| f.i2c), Some(7));
            assert!(t.verified);
            assert_eq!(t.received_at_us, u64::from(now_us) + 3);
        }
        let stats = link.stats();
        assert_eq!(stats.mode, Mode::Strict);
        assert_eq!(stats.batches, 5);
        assert_eq!(stats.incomplete_batches, 0);
        assert_eq!(stats.link.batches_discarded(), 0);
        // The Mega accepted every host batch.
        assert_eq!(mcu.link_stats().batches_discarded(), 0);
        assert_eq!(mcu.link_stats().batches_ok, 4);
    }

    #[test]
    fn pwm_commands_reach_the_mcu() {
        let mut mcu = Mcu::new(McuConfig::default());
        let mut link = MegaLink::default();
        let bytes = link.encode_pwm([40, -60, 0, 255], false);
        mcu.receive(&bytes, 0);
        let mut pwm = [0; 4];
        for tick in 1..=3 {
            pwm = mcu
                .control_tick(tick * 20_000, &TickInputs::default())
                .actuation
                .pwm;
        }
        assert_eq!(pwm, [40, -60, 0, 255]);
        assert!(!mcu.solenoid_on());
    }

    #[test]
    fn non_finite_references_are_refused() {
        let mut link = MegaLink::default();
        assert_eq!(
            link.encode_references([0.0, 0.0, f32::INFINITY, 0.0], false, false),
            Err(EncodeError::NotFinite {
                wheel: 2,
                value: f32::INFINITY
            })
        );
    }

    #[test]
    fn original_mega_stream_completes_on_s() {
        let mut link = MegaLink::default();
        let mut stream = frames(&[(b'r', 0)]);
        stream.extend(original_batch([1, 2, 3, 4], 20_004, 1));
        stream.extend(original_batch([11, 12, 13, -4], 20_056, 0));
        // The first batch completes on its `s`, before the second batch arrives.
        let split = FRAME_LEN * 7;
        let first = collect(&mut link, &stream[..split], 100);
        assert_eq!(first.len(), 2);
        assert_eq!(
            first[0],
            MegaEvent::Reset {
                received_at_us: 100
            }
        );
        let t = telemetry(&first)[0];
        assert_eq!(t.totals, [1, 2, 3, 4]);
        assert_eq!(t.deltas_ticks, None);
        assert_eq!(t.period_us, 20_004);
        assert!(!t.switch_pressed);
        assert!(!t.verified);
        assert_eq!(t.quadrature_errors, None);
        let t = telemetry(&collect(&mut link, &stream[split..], 200))[0];
        assert_eq!(t.totals, [11, 12, 13, -4]);
        assert_eq!(t.deltas_ticks, Some([10, 10, 10, -8]));
        assert!(t.switch_pressed);
        assert_eq!(link.stats().mode, Mode::Compatible);
        assert_eq!(link.stats().batches, 2);
    }

    #[test]
    fn unchecked_stream_of_our_mega_reports_diagnostics_one_batch_late() {
        let mut mcu = Mcu::new(McuConfig {
            send_checksums: false,
            ..McuConfig::default()
        });
        let mut link = MegaLink::default();
        let mut got = Vec::new();
        for tick in 1..=2u32 {
            let inputs = TickInputs {
                quadrature_errors: [tick as u8; 4],
                ..TickInputs::default()
            };
            let out = mcu.control_tick(tick * 20_000, &inputs);
            got.extend(telemetry(&collect(&mut link, out.telemetry.as_bytes(), 0)));
        }
        assert_eq!(got.len(), 2);
        assert_eq!(got[0].quadrature_errors, None);
        assert_eq!(got[1].quadrature_errors, Some(QuadratureErrors([1; 4])));
        assert_eq!(link.stats().incomplete_batches, 0);
    }

    #[test]
    fn a_reset_mid_stream_restarts_the_totals() {
        let mut link = MegaLink::default();
        let mut stream = original_batch([1000, 1000, 1000, 1000], 20_000, 1);
        // Half a batch, then the Mega reboots.
        stream.extend(frames(&[(b'g', 1010), (b'h', 1010)]));
        stream.extend(frames(&[(b'r', 0)]));
        stream.extend(original_batch([3, 3, 3, 3], 20_000, 1));
        stream.extend(original_batch([5, 6, 7, 8], 20_000, 1));
        let events = collect(&mut link, &stream, 0);
        assert_eq!(events.len(), 4);
        assert!(matches!(events[1], MegaEvent::Reset { .. }));
        let t = telemetry(&events);
        assert_eq!(t[0].totals, [1000; 4]);
        assert_eq!(t[1].totals, [3; 4]);
        assert_eq!(t[1].deltas_ticks, None, "no delta across a reset");
        assert_eq!(t[2].deltas_ticks, Some([2, 3, 4, 5]));
        let stats = link.stats();
        assert_eq!(stats.resets, 1);
        assert_eq!(stats.incomplete_batches, 1);
    }

    #[test]
    fn a_reset_of_a_checksumming_mega_is_accepted_in_strict_mode() {
        let mut mcu = Mcu::new(McuConfig::default());
        let mut link = MegaLink::default();
        collect(&mut link, mcu.boot().as_bytes(), 0);
        for tick in 1..=3 {
            let out = mcu.control_tick(tick * 20_000, &TickInputs::default());
            collect(&mut link, out.telemetry.as_bytes(), 0);
        }
        assert_eq!(link.stats().mode, Mode::Strict);
        // A new Mega (rebooted): its sequence restarts at 0.
        let mut mcu = Mcu::new(McuConfig::default());
        let events = collect(&mut link, mcu.boot().as_bytes(), 70_000);
        assert_eq!(
            events,
            [MegaEvent::Reset {
                received_at_us: 70_000
            }]
        );
        let inputs = TickInputs {
            encoder_deltas: [1, 2, 3, 4],
            ..TickInputs::default()
        };
        let out = mcu.control_tick(20_000, &inputs);
        let t = telemetry(&collect(&mut link, out.telemetry.as_bytes(), 80_000));
        assert_eq!(t.len(), 1);
        assert_eq!(t[0].totals, [1, 2, 3, 4]);
        assert_eq!(t[0].deltas_ticks, None);
        assert_eq!(link.stats().link.batches_discarded(), 0);
    }

    #[test]
    fn corrupted_bytes_are_counted_and_the_batch_dropped() {
        let mut mcu = Mcu::new(McuConfig::default());
        let mut link = MegaLink::default();
        let mut stream = Vec::new();
        for tick in 1..=4 {
            let inputs = TickInputs {
                encoder_deltas: [10, 10, 10, 10],
                ..TickInputs::default()
            };
            stream.push(
                mcu.control_tick(tick * 20_000, &inputs)
                    .telemetry
                    .as_bytes()
                    .to_vec(),
            );
        }
        // Batch 3: a hex digit of `h` changes (still a valid frame, wrong value).
        stream[2][FRAME_LEN + 8] ^= 0x01;
        // Batch 4: a byte that aborts a frame.
        stream[3][3] = b'#';
        let mut got = Vec::new();
        for batch in &stream {
            got.extend(telemetry(&collect(&mut link, batch, 0)));
        }
        let totals: Vec<[i32; 4]> = got.iter().map(|t| t.totals).collect();
        assert_eq!(totals, [[10; 4], [20; 4]]);
        let stats = link.stats();
        assert_eq!(stats.link.batches_corrupt, 2);
        assert_eq!(stats.link.frames_aborted, 1);
        assert_eq!(stats.batches, 2);
    }

    #[test]
    fn corruption_in_compatible_mode_is_counted() {
        let mut link = MegaLink::default();
        let mut stream = original_batch([1, 1, 1, 1], 20_000, 1);
        let mut bad = original_batch([2, 2, 2, 2], 20_000, 1);
        bad[FRAME_LEN + 4] = b'#'; // aborts `h`: the batch lacks a wheel
        stream.extend(bad);
        stream.extend(original_batch([3, 3, 3, 3], 20_000, 1));
        let t = telemetry(&collect(&mut link, &stream, 0));
        let totals: Vec<[i32; 4]> = t.iter().map(|t| t.totals).collect();
        assert_eq!(totals, [[1; 4], [3; 4]]);
        assert_eq!(t[1].deltas_ticks, Some([2; 4]));
        let stats = link.stats();
        assert_eq!(stats.link.frames_aborted, 1);
        assert_eq!(stats.incomplete_batches, 1);
    }

    #[test]
    fn watchdog_uses_the_age_of_the_last_reference() {
        let timeout = DEFAULT_REFERENCE_TIMEOUT_US;
        assert_eq!(reference_age_us(Some(1_000), 1_500), Some(500));
        assert_eq!(reference_age_us(None, 1_500), None);
        assert_eq!(reference_age_us(Some(2_000), 1_500), None);
        assert!(reference_is_stale(None, 0, timeout));
        assert!(!reference_is_stale(Some(0), timeout, timeout));
        assert!(reference_is_stale(Some(0), timeout + 1, timeout));
        // Clock going backwards is treated as stale.
        assert!(reference_is_stale(Some(10), 5, timeout));
        // The original's bug: a publisher that died leaves its last reference forever.
        // Here, it is zeroed once old, without any new message arriving.
        let speeds = [1.0, 2.0, 3.0, 4.0];
        assert_eq!(
            guarded_references(speeds, Some(0), 100_000, timeout),
            speeds
        );
        assert_eq!(
            guarded_references(speeds, Some(0), 300_000, timeout),
            [0.0; 4]
        );
    }

    proptest! {
        #[test]
        fn any_chunking_gives_the_same_events(
            cuts in proptest::collection::vec(any::<usize>(), 0..10),
            checksums in any::<bool>(),
        ) {
            let mut mcu = Mcu::new(McuConfig { send_checksums: checksums, ..McuConfig::default() });
            let mut stream = mcu.boot().as_bytes().to_vec();
            for tick in 1..=6 {
                let inputs = TickInputs {
                    encoder_deltas: [tick, -tick, 2 * tick, 3],
                    switch_pressed: tick % 3 == 0,
                    ..TickInputs::default()
                };
                stream.extend_from_slice(
                    mcu.control_tick(tick as u32 * 20_000, &inputs).telemetry.as_bytes());
            }
            let whole = collect(&mut MegaLink::default(), &stream, 0);
            prop_assert_eq!(whole.len(), 7);
            let mut cuts: Vec<usize> = cuts.iter().map(|c| c % (stream.len() + 1)).collect();
            cuts.sort_unstable();
            let mut link = MegaLink::default();
            let mut pieces = Vec::new();
            let mut at = 0;
            for cut in cuts.into_iter().chain([stream.len()]) {
                pieces.extend(collect(&mut link, &stream[at..cut], 0));
                at = cut;
            }
            prop_assert_eq!(pieces, whole);
        }

        #[test]
        fn random_bytes_never_panic(
            bytes in proptest::collection::vec(
                prop_oneof![any::<u8>(), Just(b'g'), Just(b's'), Just(b'z'), Just(b'0')], 0..400)
        ) {
            let mut link = MegaLink::default();
            let events = collect(&mut link, &bytes, 0);
            let stats = link.stats();
            prop_assert_eq!(
                events.len() as u32,
                stats.batches + stats.resets
            );
        }
    }
}
