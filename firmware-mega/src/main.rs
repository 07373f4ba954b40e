//! The ratf robot's Arduino Mega 2560 firmware: four quadrature encoders, the Adafruit Motor
//! Shield V2, the box switch and the electromagnet, and the serial link to the Raspberry Pi.
//!
//! The behaviour (commands, control loop, watchdog, telemetry) is `ratf_protocol::mcu::Mcu`,
//! the same state machine the host simulator runs; this crate only feeds it the hardware's
//! inputs and applies its outputs. Boundary: `hw` is the only module with registers, interrupts
//! and `unsafe`; everything else is plain logic. See `README.md` for the design and figures.
#![no_std]
#![no_main]
#![feature(abi_avr_interrupt)]
#![feature(asm_experimental_arch)]
#![deny(unsafe_code)]

#[cfg(feature = "bench-pi")]
mod bench;
mod board;
mod encoder_fold;
#[allow(unsafe_code)]
mod hw;
mod motor_shield;
mod quadrature_tables;
mod ring;

use hw::delay::BusyDelay;
use hw::encoders::Encoders;
use hw::gpio::Gpio;
use hw::twi::Twi;
use hw::usart::Usart;
use motor_shield::MotorShield;
use ratf_protocol::mcu::{Mcu, McuConfig, TickInputs};

/// Received bytes handed to the state machine per loop pass.
const RX_CHUNK: usize = 32;

#[avr_device::entry]
fn main() -> ! {
    let dp = hw::take_peripherals();
    let mut gpio = Gpio::new(dp.PORTA, dp.PORTB, dp.PORTC);
    let mut usart = Usart::new(dp.USART0);
    let mut shield = MotorShield::new(Twi::new(dp.TWI));
    let mut delay = BusyDelay;
    let mut mcu = Mcu::new(McuConfig::default());
    // The benchmark (feature `bench-pi`) runs before any interrupt is enabled.
    #[cfg(feature = "bench-pi")]
    bench::run(&dp.TC4, &mut usart);
    shield.apply([0; 4], &mut delay);
    // The encoder pull-ups were enabled by Gpio::new, long enough ago to have settled.
    let mut encoders = Encoders::start(dp.TC1, dp.TC3, &dp.CPU, gpio.encoder_pins());
    hw::enable_interrupts();
    usart.start_receiving();
    usart.write(mcu.boot().as_bytes());

    let mut rx = [0u8; RX_CHUNK];
    loop {
        let n = usart.read(&mut rx);
        if n > 0 {
            mcu.receive(&rx[..n], encoders.now_us());
            gpio.set_solenoid(mcu.solenoid_on());
        }
        if let Some(sample) = encoders.take_sample() {
            // The counters are wrapping; `x` carries their low byte.
            let inputs = TickInputs {
                encoder_deltas: sample.encoder_deltas,
                switch_pressed: gpio.switch_pressed(),
                quadrature_errors: sample.quadrature_errors,
                i2c_faults: shield.faults() as u8,
                serial_bytes_dropped: usart.bytes_dropped(),
            };
            // Telemetry first, then the controllers and the I2C writes: the batch leaves at
            // the same time after every tick, whatever the motors are doing.
            usart.write(mcu.begin_tick(sample.now_us, &inputs).as_bytes());
            let actuation = mcu.finish_tick(sample.now_us);
            gpio.set_solenoid(actuation.solenoid_on);
            shield.apply(actuation.pwm, &mut delay);
        }
    }
}
