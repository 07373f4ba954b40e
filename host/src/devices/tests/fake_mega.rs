//! The Mega on the far side of a pseudo-terminal: `protocol::mcu`, the Mega's own logic,
//! stepped by the test's thread on the wall clock. Every opening of its port resets it
//! (DTR), and it sends its `r` a boot delay later, after the bootloader's wait. It runs a
//! control tick every 20 ms (telemetry out, PWM and magnet applied to wheels whose encoders
//! then turn), on while nobody has the port open (powered, its telemetry going nowhere), and
//! logs what the host wrote, decoded, with its arrival time.
//!
//! [`FakeMega::noisy`] puts random bytes on the line between telemetry batches and into the
//! Mega's receiver before each chunk from the host: line noise both ways, each way from its
//! own generator, so what the host receives depends on the seed alone.

use std::time::{Duration, Instant};

use ratf_core::rng::SimRng;
use ratf_protocol::integrity::{BatchReceiver, HOST_CHECKSUM_CHANNEL, LinkStats};
use ratf_protocol::mcu::{Mcu, McuConfig, TickInputs};
use ratf_protocol::messages::{Command, WHEEL_COUNT};

use super::pty::Pty;

/// The Mega's control period.
pub(crate) const CONTROL_PERIOD: Duration = Duration::from_millis(20);

/// Encoder ticks per control period per unit of PWM (a wheel at PWM 80 turns 10 ticks).
const TICKS_PER_PWM: i16 = 8;

/// Most bytes of noise put on the line at once.
const MAX_GARBAGE: u64 = 12;

/// One batch the host wrote (`G H I J L`; the `U` after it is not kept), as the Mega's own
/// decoder saw it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct HostBatch {
    /// When its last byte was read.
    pub(crate) at: Instant,
    /// The four wheel references, rad/s.
    pub(crate) speeds: [Option<f32>; WHEEL_COUNT],
    /// The magnet.
    pub(crate) solenoid: Option<bool>,
}

impl HostBatch {
    /// Zero references and magnet off.
    pub(crate) fn is_stop(&self) -> bool {
        self.speeds.iter().all(|s| *s == Some(0.0)) && self.solenoid == Some(false)
    }

    /// Every wheel referenced at `speed`, magnet `on`.
    pub(crate) fn is(&self, speed: f32, on: bool) -> bool {
        self.speeds.iter().all(|s| *s == Some(speed)) && self.solenoid == Some(on)
    }
}

/// One control tick of the Mega.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct TickRecord {
    /// When.
    pub(crate) at: Instant,
    /// PWM applied per wheel.
    pub(crate) pwm: [i16; WHEEL_COUNT],
    /// Magnet applied.
    pub(crate) solenoid_on: bool,
    /// The Mega's watchdog had the motors stopped.
    pub(crate) timed_out: bool,
}

impl TickRecord {
    /// Wheels at rest and magnet off.
    pub(crate) fn stopped(&self) -> bool {
        self.pwm == [0; WHEEL_COUNT] && !self.solenoid_on
    }
}

/// The emulated Mega: see the module documentation.
pub(crate) struct FakeMega {
    /// Its port.
    pub(crate) pty: Pty,
    mcu: Mcu,
    epoch: Instant,
    boot_delay: Duration,
    plugged_at: Option<Instant>,
    booted: bool,
    next_tick: Instant,
    decoder: BatchReceiver<8>,
    current: HostBatch,
    pwm: [i16; WHEEL_COUNT],
    noise_to_host: Option<SimRng>,
    noise_to_mega: Option<SimRng>,
    /// Bytes the host wrote before the Mega's `r`, one entry per time the port was opened.
    pub(crate) before_boot: Vec<Vec<u8>>,
    /// On each opening, one telemetry batch of the board's life before the reset reaches the
    /// host first (it waited in the port's buffers).
    pub(crate) stale_batch_on_open: bool,
    /// Every batch the host wrote after the `r`.
    pub(crate) batches: Vec<HostBatch>,
    /// Every control tick.
    pub(crate) ticks: Vec<TickRecord>,
    /// When the Mega sent its `r`.
    pub(crate) boots: Vec<Instant>,
}

impl FakeMega {
    /// A Mega behind `pty` that sends its `r` `boot_delay` after its port is opened.
    pub(crate) fn new(pty: Pty, boot_delay: Duration) -> Self {
        let now = Instant::now();
        Self {
            pty,
            mcu: Mcu::new(McuConfig::default()),
            epoch: now,
            boot_delay,
            plugged_at: None,
            booted: false,
            next_tick: now,
            decoder: BatchReceiver::new(HOST_CHECKSUM_CHANNEL),
            current: empty_batch(now),
            pwm: [0; WHEEL_COUNT],
            noise_to_host: None,
            noise_to_mega: None,
            before_boot: Vec::new(),
            stale_batch_on_open: false,
            batches: Vec::new(),
            ticks: Vec::new(),
            boots: Vec::new(),
        }
    }

    /// Line noise both ways from now on, drawn from `seed`.
    pub(crate) fn noisy(&mut self, seed: u64) {
        let rng = SimRng::new(seed);
        self.noise_to_host = Some(rng.fork("to the host"));
        self.noise_to_mega = Some(rng.fork("to the Mega"));
    }

    /// The Mega's receive counters since its last boot.
    pub(crate) fn link_stats(&self) -> LinkStats {
        self.mcu.link_stats()
    }

    /// The configuration the Mega's logic uses now (its defaults plus the host's settings
    /// since its last boot).
    pub(crate) fn mcu_config(&self) -> McuConfig {
        *self.mcu.config()
    }

    /// Batches the host wrote at or after `since`.
    pub(crate) fn batches_since(&self, since: Instant) -> impl Iterator<Item = &HostBatch> {
        self.batches.iter().filter(move |b| b.at >= since)
    }

    /// Ticks at or after `since`.
    pub(crate) fn ticks_since(&self, since: Instant) -> impl Iterator<Item = &TickRecord> {
        self.ticks.iter().filter(move |t| t.at >= since)
    }

    /// Be the Mega until `until`.
    pub(crate) fn service(&mut self, until: Instant) {
        loop {
            let now = Instant::now();
            if now >= until {
                return;
            }
            let connected = self.pty.connected();
            if !connected {
                // Nobody has the port open: the board runs on (its telemetry goes nowhere),
                // and the next opening resets it.
                self.plugged_at = None;
            } else if self.plugged_at.is_none() {
                // Opening the port pulled DTR: the board resets, silent until it boots.
                if self.stale_batch_on_open {
                    let stale = self
                        .mcu
                        .control_tick(self.now_us(now), &TickInputs::default());
                    self.pty.write(stale.telemetry.as_bytes());
                }
                self.plugged_at = Some(now);
                self.before_boot.push(Vec::new());
                self.booted = false;
            }
            let next_event = match self.plugged_at {
                Some(plugged_at) if !self.booted => {
                    if now >= plugged_at + self.boot_delay {
                        self.boot(now);
                    }
                    plugged_at + self.boot_delay
                }
                _ if self.booted => self.next_tick,
                _ => now + Duration::from_millis(1),
            };
            let bytes = self.pty.read_until(until.min(next_event));
            let now = Instant::now();
            if !bytes.is_empty() {
                self.received(&bytes, now);
            }
            if self.booted && now >= self.next_tick {
                self.tick(now, connected);
            }
        }
    }

    fn boot(&mut self, now: Instant) {
        self.mcu = Mcu::new(McuConfig::default());
        self.decoder = BatchReceiver::new(HOST_CHECKSUM_CHANNEL);
        self.current = empty_batch(now);
        self.pwm = [0; WHEEL_COUNT];
        let boot = self.mcu.boot();
        self.pty.write(boot.as_bytes());
        self.booted = true;
        self.boots.push(now);
        self.next_tick = now + CONTROL_PERIOD;
    }

    fn now_us(&self, at: Instant) -> u32 {
        // The Mega's clock is a wrapping u32 of µs.
        at.duration_since(self.epoch).as_micros() as u32
    }

    fn received(&mut self, bytes: &[u8], now: Instant) {
        if !self.booted {
            if let Some(before) = self.before_boot.last_mut() {
                before.extend_from_slice(bytes);
            }
            return;
        }
        let now_us = self.now_us(now);
        let noise = noise(self.noise_to_mega.as_mut());
        self.mcu.receive(&noise, now_us);
        self.mcu.receive(bytes, now_us);
        let Self {
            decoder,
            current,
            batches,
            ..
        } = self;
        decoder.feed(bytes, |frame| match Command::from_frame(frame) {
            Ok(Command::WheelSpeed { wheel, speed_rad_s }) => {
                current.speeds[wheel.index()] = Some(speed_rad_s);
            }
            Ok(Command::Solenoid { on }) => {
                current.solenoid = Some(on);
                current.at = now;
                batches.push(*current);
                *current = empty_batch(now);
            }
            Ok(
                Command::MotorPwm { .. } | Command::Setting { .. } | Command::StopOnSwitch { .. },
            )
            | Err(_) => {}
        });
    }

    fn tick(&mut self, now: Instant, connected: bool) {
        let inputs = TickInputs {
            encoder_deltas: self.pwm.map(|pwm| pwm / TICKS_PER_PWM),
            ..TickInputs::default()
        };
        let output = self.mcu.control_tick(self.now_us(now), &inputs);
        self.pwm = output.actuation.pwm;
        self.ticks.push(TickRecord {
            at: now,
            pwm: output.actuation.pwm,
            solenoid_on: output.actuation.solenoid_on,
            timed_out: self.mcu.timed_out(),
        });
        let mut bytes = noise(self.noise_to_host.as_mut());
        bytes.extend_from_slice(output.telemetry.as_bytes());
        if connected {
            self.pty.write(&bytes);
        }
        self.next_tick += CONTROL_PERIOD;
        if self.next_tick <= now {
            // The test's thread was held up: carry on from now, as a late timer would.
            self.next_tick = now + CONTROL_PERIOD;
        }
    }
}

fn empty_batch(at: Instant) -> HostBatch {
    HostBatch {
        at,
        speeds: [None; WHEEL_COUNT],
        solenoid: None,
    }
}

/// Up to [`MAX_GARBAGE`] random bytes from `rng` (none without one).
fn noise(rng: Option<&mut SimRng>) -> Vec<u8> {
    let Some(rng) = rng else {
        return Vec::new();
    };
    let n = rng.next_u64() % (MAX_GARBAGE + 1);
    (0..n).map(|_| rng.next_u64() as u8).collect()
}
