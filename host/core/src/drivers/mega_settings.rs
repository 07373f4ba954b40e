//! When the host sends the Mega its controller settings (`ratf_protocol::settings`).
//!
//! The robot's `[mega]`, `robot.ticks_per_wheel_rev` and `motor.battery_voltage_v` are the
//! one source of truth; the firmware only has compiled defaults. So the host sends the
//! settings batch ([`MegaLink::encode_settings`]):
//!
//! - before its first write after the link comes up;
//! - after every Mega reset (`r`): a reset brings the firmware's defaults back;
//! - when the Mega's acknowledgement (`y`) does not confirm them (a lost or refused batch),
//!   at most once every [`RESEND_AFTER_BATCHES`] telemetry batches.
//!
//! An original Mega never acknowledges (no `y`), so it gets the batch only at start-up and
//! after each reset, and ignores it.

use ratf_protocol::mcu::McuConfig;
use ratf_protocol::settings::{SETTING_COUNT, SettingsAck};

use super::mega_link::{MegaEvent, MegaLink};

/// Telemetry batches (20 ms each) after a send before an unconfirming `y` triggers another
/// send: 25, half a second, long enough for the batch to arrive and be acknowledged.
pub const RESEND_AFTER_BATCHES: u32 = 25;

/// The settings to keep on the Mega, and whether they are due: see the module
/// documentation.
#[derive(Clone, Debug)]
pub struct SettingsSync {
    config: McuConfig,
    expected: [f32; SETTING_COUNT],
    due: bool,
    batches_since_send: u32,
    sends: u32,
    last_ack: Option<SettingsAck>,
}

impl SettingsSync {
    /// Keep `config`'s settings on the Mega; due at once.
    pub fn new(config: McuConfig) -> Self {
        Self {
            expected: config.setting_values(),
            config,
            due: true,
            batches_since_send: 0,
            sends: 0,
            last_ack: None,
        }
    }

    /// The settings kept on the Mega.
    pub fn config(&self) -> &McuConfig {
        &self.config
    }

    /// Send again before the next write (e.g. the port was reopened).
    pub fn mark_due(&mut self) {
        self.due = true;
    }

    /// Account for an event from the Mega.
    pub fn on_event(&mut self, event: &MegaEvent) {
        match event {
            MegaEvent::Reset { .. } => self.due = true,
            MegaEvent::Telemetry(telemetry) => {
                self.batches_since_send = self.batches_since_send.saturating_add(1);
                self.last_ack = telemetry.settings_ack;
                if !self.confirmed() && self.batches_since_send >= RESEND_AFTER_BATCHES {
                    self.due = true;
                }
            }
        }
    }

    /// True when the Mega's latest `y` confirms every setting (values equal, none refused).
    /// False for an original Mega, which never sends `y`.
    pub fn confirmed(&self) -> bool {
        self.last_ack
            .is_some_and(|ack| ack.confirms(&self.expected))
    }

    /// The Mega's latest acknowledgement, if any.
    pub fn last_ack(&self) -> Option<SettingsAck> {
        self.last_ack
    }

    /// The settings batch's bytes if it is due (then no longer due), encoded by `link`.
    pub fn take_due(&mut self, link: &mut MegaLink) -> Option<Vec<u8>> {
        if !self.due {
            return None;
        }
        self.due = false;
        self.batches_since_send = 0;
        self.sends = self.sends.wrapping_add(1);
        Some(link.encode_settings(&self.config))
    }

    /// Settings batches encoded so far.
    pub fn sends(&self) -> u32 {
        self.sends
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ratf_protocol::mcu::{Mcu, TickInputs};

    fn tuned() -> McuConfig {
        let mut config = McuConfig::default();
        config.pi.gains.kc_v_per_rad_s = 0.8;
        config.pi.gains.ki_v_per_rad = 6.0;
        config.pi.gains.kf_v_per_rad_s = 0.1;
        config.pi.dead_zone.v0_v = 0.3;
        config.pi.dead_zone.vd_v = 0.1;
        config.battery_voltage_v = 12.0;
        config.voltage_limit_v = 11.5;
        config.ticks_per_wheel_rev = 1920.0;
        config
    }

    /// The Mega's bytes through the host's link into the sync, and the sync's due batch
    /// (if any) into the Mega, as the device thread and writer do.
    fn exchange(
        mega: &mut Mcu,
        mega_bytes: &[u8],
        host: &mut MegaLink,
        sync: &mut SettingsSync,
        now_us: u32,
    ) {
        host.feed(mega_bytes, u64::from(now_us), |event| sync.on_event(&event));
        if let Some(bytes) = sync.take_due(host) {
            mega.receive(&bytes, now_us);
        }
    }

    #[test]
    fn settings_are_sent_at_start_and_resent_after_a_mega_reset() {
        let mut host = MegaLink::default();
        let mut sync = SettingsSync::new(tuned());
        let mut mega = Mcu::new(McuConfig::default());
        let boot = mega.boot();
        exchange(&mut mega, boot.as_bytes(), &mut host, &mut sync, 0);
        assert_eq!(*mega.config(), tuned());
        let out = mega.control_tick(20_000, &TickInputs::default());
        exchange(
            &mut mega,
            out.telemetry.as_bytes(),
            &mut host,
            &mut sync,
            20_000,
        );
        assert!(sync.confirmed(), "{:?}", sync.last_ack());
        assert_eq!(sync.sends(), 1);
        for i in 2..100 {
            let out = mega.control_tick(i * 20_000, &TickInputs::default());
            exchange(
                &mut mega,
                out.telemetry.as_bytes(),
                &mut host,
                &mut sync,
                i * 20_000,
            );
        }
        assert_eq!(sync.sends(), 1, "confirmed settings are not resent");

        // The Mega resets: its defaults are back until the host resends.
        let mut mega = Mcu::new(McuConfig::default());
        assert_ne!(*mega.config(), tuned());
        let boot = mega.boot();
        exchange(&mut mega, boot.as_bytes(), &mut host, &mut sync, 0);
        assert_eq!(sync.sends(), 2);
        assert_eq!(*mega.config(), tuned());
        let out = mega.control_tick(20_000, &TickInputs::default());
        exchange(
            &mut mega,
            out.telemetry.as_bytes(),
            &mut host,
            &mut sync,
            20_000,
        );
        assert!(sync.confirmed());
    }

    #[test]
    fn a_lost_batch_is_resent_when_y_does_not_confirm() {
        let mut host = MegaLink::default();
        let mut sync = SettingsSync::new(tuned());
        let mut mega = Mcu::new(McuConfig::default());
        // The first batch is lost on the way.
        assert!(sync.take_due(&mut host).is_some());
        let mut resent_at = None;
        for i in 1..60u32 {
            let out = mega.control_tick(i * 20_000, &TickInputs::default());
            exchange(
                &mut mega,
                out.telemetry.as_bytes(),
                &mut host,
                &mut sync,
                i * 20_000,
            );
            if resent_at.is_none() && sync.sends() == 2 {
                resent_at = Some(i);
            }
        }
        assert_eq!(resent_at, Some(RESEND_AFTER_BATCHES));
        assert_eq!(*mega.config(), tuned());
        assert!(sync.confirmed());
    }
}
