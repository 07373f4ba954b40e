//! Boot-time benchmark (feature `bench-pi`): the cycle cost of one wheel PI step in f32
//! (`ratf_protocol::pi::PiController::step`, with avr-libc's float routines linked by
//! `hw::float`) against the same controller in I16F16 fixed point (`fixed` crate).
//!
//! Each variant runs over 16 (reference, measurement) inputs; the line printed is the worst
//! case, in cycles of Timer4 at clk/1, minus the cost of an empty measurement. It runs before
//! interrupts are enabled, so nothing interferes. Output, one line before the boot frame:
//! `BENCH overhead=<n> f32=<n> i16f16=<n> i16f16_saturating=<n>` (decimal cycles).

use crate::hw::cycles::CycleCounter;
use crate::hw::usart::Usart;
use avr_device::atmega2560::TC4;
use core::hint::black_box;
use fixed::types::I16F16;
use ratf_protocol::integrity::{BatchWriter, HOST_CHECKSUM_CHANNEL};
use ratf_protocol::mcu::{Mcu, McuConfig, TickInputs};
use ratf_protocol::messages::{Command, Wheel};
use ratf_protocol::pi::{PiConfig, PiController};

/// Control period, s (20 ms).
const DT_S: f32 = 0.02;
/// Actuator limit, V (the battery's 11.1 V, `McuConfig::default`).
const LIMIT_V: f32 = 11.1;

/// The PI of `ratf_protocol::pi` with its default gains and no dead zone, in I16F16:
/// `u = Kc·e + Ki·I* + Kf·r`, conditional integration, clamp to ± the limit.
struct FixedPi {
    kc: I16F16,
    ki: I16F16,
    kf: I16F16,
    integral: I16F16,
    saturating: bool,
}

impl FixedPi {
    fn new(saturating: bool) -> Self {
        let gains = PiConfig::default().gains;
        Self {
            kc: I16F16::from_num(gains.kc_v_per_rad_s),
            ki: I16F16::from_num(gains.ki_v_per_rad),
            kf: I16F16::from_num(gains.kf_v_per_rad_s),
            integral: I16F16::ZERO,
            saturating,
        }
    }

    fn mul(&self, a: I16F16, b: I16F16) -> I16F16 {
        if self.saturating {
            a.saturating_mul(b)
        } else {
            a * b
        }
    }

    fn step(&mut self, reference: I16F16, measured: I16F16, dt: I16F16, limit: I16F16) -> I16F16 {
        let error = reference - measured;
        let candidate = if reference == I16F16::ZERO {
            I16F16::ZERO
        } else {
            self.integral + self.mul(error, dt)
        };
        let output = |this: &Self, integral: I16F16| {
            this.mul(this.kc, error) + this.mul(this.ki, integral) + this.mul(this.kf, reference)
        };
        let mut u = output(self, candidate);
        let winding_up =
            (u > limit && candidate > I16F16::ZERO) || (u < -limit && candidate < I16F16::ZERO);
        if winding_up {
            u = output(self, self.integral);
        } else {
            self.integral = candidate;
        }
        u.clamp(-limit, limit)
    }
}

/// The 16 inputs: references and measurements, rad/s, spanning stop, small and saturating.
fn input(k: u8) -> (f32, f32) {
    let reference = f32::from(k % 8) * 3.0 - 9.0;
    let measured = f32::from(k) * 0.7 - 4.0;
    (reference, measured)
}

/// Worst case over the inputs of `run(k)`, cycles, minus nothing (raw).
fn worst(counter: &CycleCounter<'_>, mut run: impl FnMut(u8)) -> u16 {
    let mut worst = 0;
    for k in 0..16 {
        let start = counter.now();
        run(black_box(k));
        let spent = counter.now().wrapping_sub(start);
        worst = worst.max(spent);
    }
    worst
}

/// Run the benchmark and print its line.
pub fn run(tc4: &TC4, usart: &mut Usart) {
    let counter = CycleCounter::start(tc4);
    let overhead = worst(&counter, |k| {
        black_box(k);
    });
    let mut pi = PiController::new(PiConfig::default());
    let f32_cycles = worst(&counter, |k| {
        let (reference, measured) = input(k);
        black_box(pi.step(
            black_box(reference),
            black_box(measured),
            black_box(DT_S),
            black_box(LIMIT_V),
        ));
    });
    let mut fixed_results = [0u16; 2];
    for (slot, saturating) in fixed_results.iter_mut().zip([false, true]) {
        let mut pi = FixedPi::new(saturating);
        let (dt, limit) = (I16F16::from_num(DT_S), I16F16::from_num(LIMIT_V));
        let inputs: [(I16F16, I16F16); 16] = core::array::from_fn(|k| {
            let (r, m) = input(k as u8);
            (I16F16::from_num(r), I16F16::from_num(m))
        });
        *slot = worst(&counter, |k| {
            let (reference, measured) = inputs[usize::from(k)];
            black_box(pi.step(
                black_box(reference),
                black_box(measured),
                black_box(dt),
                black_box(limit),
            ));
        });
    }
    // The link: one host batch (`G H I J L Z`, 54 bytes) through `Mcu::receive`, and one
    // whole control tick with all four wheels under speed control.
    let mut mcu = Mcu::new(McuConfig::default());
    let mut writer = BatchWriter::new(HOST_CHECKSUM_CHANNEL, true);
    let mut batch = [0u8; 64];
    let commands = [
        Command::WheelSpeed {
            wheel: Wheel::BackRight,
            speed_rad_s: 5.0,
        },
        Command::WheelSpeed {
            wheel: Wheel::BackLeft,
            speed_rad_s: -5.0,
        },
        Command::WheelSpeed {
            wheel: Wheel::FrontRight,
            speed_rad_s: 5.0,
        },
        Command::WheelSpeed {
            wheel: Wheel::FrontLeft,
            speed_rad_s: -5.0,
        },
        Command::Solenoid { on: true },
    ]
    .map(|c| c.to_frame());
    let mut rx_cycles = 0;
    let mut begin_cycles = 0;
    let mut finish_cycles = 0;
    for round in 0..4u32 {
        let n = writer.write_batch(&commands, &mut batch).unwrap_or(0);
        let start = counter.now();
        mcu.receive(black_box(&batch[..n]), round * 20_000);
        rx_cycles = rx_cycles.max(counter.now().wrapping_sub(start));
        let inputs = TickInputs {
            encoder_deltas: [30, -30, 30, -30],
            ..TickInputs::default()
        };
        let now_us = round * 20_000 + 1_000;
        let start = counter.now();
        black_box(mcu.begin_tick(now_us, black_box(&inputs)));
        begin_cycles = begin_cycles.max(counter.now().wrapping_sub(start));
        let start = counter.now();
        black_box(mcu.finish_tick(now_us));
        finish_cycles = finish_cycles.max(counter.now().wrapping_sub(start));
    }
    let mut line = [0u8; 160];
    let mut len = 0;
    let mut put = |text: &[u8]| {
        for &byte in text {
            if len < line.len() {
                line[len] = byte;
                len += 1;
            }
        }
    };
    let net = |cycles: u16| cycles.saturating_sub(overhead);
    put(b"BENCH overhead=");
    put(&decimal(overhead));
    put(b" f32=");
    put(&decimal(net(f32_cycles)));
    put(b" i16f16=");
    put(&decimal(net(fixed_results[0])));
    put(b" i16f16_saturating=");
    put(&decimal(net(fixed_results[1])));
    put(b" rx_batch=");
    put(&decimal(net(rx_cycles)));
    put(b" begin_tick=");
    put(&decimal(net(begin_cycles)));
    put(b" finish_tick=");
    put(&decimal(net(finish_cycles)));
    put(b"\r\n");
    usart.write(&line[..len]);
}

/// `value` in decimal, right-aligned in 5 ASCII digits with leading spaces removed by the
/// caller's reader (leading zeros kept: simple and unambiguous).
fn decimal(value: u16) -> [u8; 5] {
    let mut digits = [b'0'; 5];
    let mut rest = value;
    for digit in digits.iter_mut().rev() {
        *digit = b'0' + (rest % 10) as u8;
        rest /= 10;
    }
    digits
}
