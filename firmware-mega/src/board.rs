//! Board facts of the Arduino Mega 2560 as wired on the robot: clock, pins, timer settings,
//! link speed and the motor shield's address. Every pin here is listed in
//! `hardware/pinmap.md` (the source of truth), by Arduino label and MCU port pin.
//!
//! Derived values are computed from the facts they depend on, and compile-time assertions
//! check the numbers quoted in the documentation.

/// CPU clock, Hz: the Mega 2560's 16 MHz crystal.
pub const F_CPU_HZ: u32 = 16_000_000;

/// Serial link to the Raspberry Pi, baud: 115200 8N1 as in the original firmware
/// (original-system.md §2.1), over the Mega's USB-serial bridge on USART0 (pins 0/1).
pub const LINK_BAUD: u32 = 115_200;
/// USART0 baud register with double speed (U2X0 = 1): `round(F_CPU / (8 * baud)) - 1` = 16.
/// 16 MHz / (8 * 17) = 117 647 baud, +2.1 % from 115 200 (ATmega2560 datasheet §22.3.1);
/// without U2X the nearest setting is −3.5 % off, so U2X is used.
pub const LINK_UBRR: u16 = ((F_CPU_HZ + 4 * LINK_BAUD) / (8 * LINK_BAUD) - 1) as u16;
const _: () = assert!(LINK_UBRR == 16);

/// Encoder sampling rate, Hz: 50 kHz, the original's 20 µs TimerOne period (§2.3).
pub const ENCODER_SAMPLE_HZ: u32 = 50_000;
/// Timer1 compare value for the sampling rate in CTC mode at clk/1: 16 MHz / 50 kHz − 1 = 319.
/// CTC (WGM mode 4), not TimerOne's phase- and frequency-correct PWM mode, which simavr does
/// not model (avr-toolchain.md, "Simulation notes").
pub const ENCODER_TIMER_TOP: u16 = (F_CPU_HZ / ENCODER_SAMPLE_HZ - 1) as u16;
const _: () = assert!(ENCODER_TIMER_TOP == 319);

/// Time base period, µs: Timer3 interrupts every millisecond to count time and fold the
/// encoder ISR's 8-bit counters into 16-bit ones (see `hw::encoders`).
pub const TIME_BASE_PERIOD_US: u32 = 1_000;
/// Timer3 prescaler: clk/8, so one timer count is 0.5 µs.
pub const TIME_BASE_PRESCALER: u32 = 8;
/// Timer3 compare value (CTC): 16 MHz / 8 × 1 ms − 1 = 1999.
pub const TIME_BASE_TIMER_TOP: u16 =
    (F_CPU_HZ / TIME_BASE_PRESCALER / (1_000_000 / TIME_BASE_PERIOD_US) - 1) as u16;
const _: () = assert!(TIME_BASE_TIMER_TOP == 1999);

/// Control period, time-base periods (ms): 20 ms = 50 Hz, the original's control rate
/// (original-system.md §2.2). Equals `McuConfig::default().control_period_us`.
pub const CONTROL_PERIOD_MS: u8 = 20;
/// Control period, µs.
pub const CONTROL_PERIOD_US: u32 = CONTROL_PERIOD_MS as u32 * TIME_BASE_PERIOD_US;
const _: () = assert!(CONTROL_PERIOD_US == 20_000);

/// Encoders: Arduino pins 22..=29 = PORTA bits 0..=7, inputs with pull-ups. Encoder `k`
/// (motor index `k`) has channel A on `PINA` bit `2k` and channel B on bit `2k + 1`
/// (original-system.md §2.1).
pub const ENCODER_PORT_MASK: u8 = 0xFF;

/// Box switch: Arduino pin 53 = PB0, input with pull-up; reads 0 when pressed (§2.1).
pub const SWITCH_PORTB_BIT: u8 = 0;
/// Solenoid (Grove electromagnet): Arduino pin 30 = PC7, output, low at boot (§2.1).
pub const SOLENOID_PORTC_BIT: u8 = 7;

/// I2C (TWI) bus speed to the motor shield, Hz. 400 kHz fast mode: the PCA9685 supports up to
/// 1 MHz (PCA9685 datasheet §1), so a 13-byte motor write takes about 0.3 ms instead of 1.2 ms
/// at the Arduino Wire library's default 100 kHz. SDA = pin 20 (PD1), SCL = pin 21 (PD0).
pub const I2C_BUS_HZ: u32 = 400_000;
/// TWI bit-rate register with prescaler 1: SCL = F_CPU / (16 + 2·TWBR) (datasheet §24.5.2).
pub const I2C_TWBR: u8 = ((F_CPU_HZ / I2C_BUS_HZ - 16) / 2) as u8;
const _: () = assert!(I2C_TWBR == 12);
/// Bound on every wait for the TWI hardware (polls of TWINT/TWSTO). One poll of the compiled
/// loop is 11 cycles (`avr-objdump -d`: `sbiw cp cpc breq lds andi cpi brne`), so the bound
/// is 11 000 cycles ≈ 0.7 ms (plus interrupt time): about 30 byte times at 400 kHz (22.5 µs
/// per byte), and the most a dead bus can cost the loop per failed transfer.
pub const I2C_WAIT_POLLS: u16 = 1_000;

/// The Adafruit Motor Shield V2's PCA9685 7-bit I2C address: 0x60 (no address jumpers set).
pub const MOTOR_SHIELD_I2C_ADDRESS: u8 = 0x60;
/// Motor PWM frequency, Hz: 1600, the Adafruit library's default `begin()` (§2.1).
pub const MOTOR_PWM_HZ: u32 = 1_600;
