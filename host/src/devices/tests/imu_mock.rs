//! The IMU's device thread against a mock I2C bus: the simulator's MPU9255
//! (`ratf_sim::imu`) behind a bus the test can break. Configuration from the robot's
//! configuration, the start-up bias measured by the core from the thread's samples, the
//! mounting's axis mapping, bus errors.

use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::mpsc::Receiver;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

use embedded_hal::i2c::{ErrorKind, ErrorType, I2c, Operation};
use ratf_core::config::Config;
use ratf_core::drivers::imu::registers::{GYRO_CONFIG, GyroRange};
use ratf_core::drivers::imu::{ImuSample, Mpu9255};
use ratf_core::field::Field;
use ratf_core::runtime::{Core, DeviceKind, Event, Input, Stamped};
use ratf_sim::imu::{SimErrors, SimI2cError, SimMotion, SimMpu9255};

use crate::devices::imu::{self, MAX_FAILED_READS};
use crate::devices::{Clock, LinkState, Message, Shared};

/// The simulated chip on a bus the test shares with the thread, and can break: a number
/// of transfers that fail, or every transfer from now on.
#[derive(Clone)]
struct MockBus {
    chip: Arc<Mutex<SimMpu9255>>,
    failures_left: Arc<AtomicU32>,
    dead: Arc<AtomicBool>,
    failed: Arc<AtomicU32>,
}

impl MockBus {
    fn new(chip: SimMpu9255) -> Self {
        Self {
            chip: Arc::new(Mutex::new(chip)),
            failures_left: Arc::new(AtomicU32::new(0)),
            dead: Arc::new(AtomicBool::new(false)),
            failed: Arc::new(AtomicU32::new(0)),
        }
    }

    fn chip(&self) -> MutexGuard<'_, SimMpu9255> {
        self.chip.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

impl ErrorType for MockBus {
    type Error = SimI2cError;
}

impl I2c for MockBus {
    fn transaction(
        &mut self,
        address: u8,
        operations: &mut [Operation<'_>],
    ) -> Result<(), Self::Error> {
        let glitch = self
            .failures_left
            .fetch_update(Ordering::SeqCst, Ordering::SeqCst, |n| n.checked_sub(1))
            .is_ok();
        if glitch || self.dead.load(Ordering::SeqCst) {
            self.failed.fetch_add(1, Ordering::SeqCst);
            return Err(SimI2cError(ErrorKind::Bus));
        }
        self.chip().transaction(address, operations)
    }
}

/// The IMU's thread on `bus`, configured from `config` as `ratf run` does.
struct ImuBench {
    rx: Receiver<Message>,
    messages: Vec<Message>,
    shared: Shared,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl ImuBench {
    fn start(bus: MockBus, config: &Config, clock: Clock) -> Self {
        let imu = Mpu9255::new(bus, config.robot.imu.driver_config()).expect("the IMU answers");
        let shared = Shared::new();
        let (tx, rx) = crate::devices::inbox(&shared);
        let yaw_rad = config.robot.imu.yaw_deg.to_radians();
        let thread =
            imu::spawn(Box::new(imu), yaw_rad, clock, tx, shared.clone()).expect("the thread");
        Self {
            rx,
            messages: Vec::new(),
            shared,
            thread: Some(thread),
        }
    }

    fn samples(&self) -> Vec<(&Stamped, &ImuSample)> {
        self.messages
            .iter()
            .filter_map(|m| match m {
                Message::Input(s) => match &s.input {
                    Input::Imu(sample) => Some((s, sample)),
                    _ => None,
                },
                _ => None,
            })
            .collect()
    }

    /// Collect messages until `done`; panics naming `what` after `timeout`.
    fn wait_for(&mut self, timeout: Duration, what: &str, done: impl Fn(&Self) -> bool) {
        let deadline = Instant::now() + timeout;
        while !done(self) {
            let left = deadline.saturating_duration_since(Instant::now());
            assert!(
                !left.is_zero(),
                "{what}: not within {timeout:?}; {} samples",
                self.samples().len()
            );
            if let Ok(message) = self.rx.recv_timeout(left.min(Duration::from_millis(10))) {
                self.messages.push(message);
            }
        }
    }
}

impl Drop for ImuBench {
    fn drop(&mut self) {
        self.shared.request_quit();
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

#[test]
fn the_imu_is_configured_from_the_config_and_its_samples_come_in_the_robots_axes() {
    let mut config = Config::default();
    config.robot.imu.gyro_range_dps = 1000;
    config.robot.imu.yaw_deg = 90.0;
    let mut chip = SimMpu9255::new(3);
    chip.set_motion(SimMotion {
        rate_rad_s: [0.3, 0.0, 0.5],
        accel_m_s2: [1.0, 0.0, 9.806_65],
    });
    let bus = MockBus::new(chip);
    let clock = Clock::start();
    let mut bench = ImuBench::start(bus.clone(), &config, clock);
    assert_eq!(
        bus.chip().writes(),
        config.robot.imu.driver_config().register_writes(),
        "every setting written"
    );
    assert_eq!(
        GyroRange::from_register(bus.chip().register(GYRO_CONFIG)),
        GyroRange::Dps1000
    );
    bench.wait_for(Duration::from_secs(2), "20 samples", |b| {
        b.samples().len() >= 20
    });
    assert_eq!(
        bench.messages[0],
        Message::Link(DeviceKind::Imu, LinkState::Up)
    );
    // One LSB at ±1000 °/s and at ±4 g.
    let gyro_lsb = (1.0f64 / 32.8).to_radians();
    let accel_lsb = 9.806_65 / 8192.0;
    for (stamped, sample) in bench.samples() {
        assert_eq!(stamped.time.as_us(), sample.time_us, "stamped when read");
        // The chip's x (forward on the chip) is the robot's y: mounted turned 90° left.
        let gyro = [0.0, 0.3, 0.5];
        let accel = [0.0, 1.0, 9.806_65];
        for axis in 0..3 {
            assert!(
                (sample.gyro_rad_s[axis] - gyro[axis]).abs() <= gyro_lsb,
                "{sample:?}"
            );
            assert!(
                (sample.accel_m_s2[axis] - accel[axis]).abs() <= accel_lsb,
                "{sample:?}"
            );
        }
    }
    let times: Vec<u64> = bench
        .samples()
        .iter()
        .map(|(s, _)| s.time.as_us())
        .collect();
    assert!(times.windows(2).all(|w| w[0] < w[1]), "{times:?}");
}

#[test]
fn the_core_measures_the_start_up_bias_from_the_threads_samples() {
    let config = Config::default();
    let mut chip = SimMpu9255::new(4);
    let bias_z = 0.004;
    chip.set_errors(SimErrors {
        gyro_bias_rad_s: [0.01, -0.02, bias_z],
        gyro_noise_std_rad_s: 0.002,
        accel_noise_std_m_s2: 0.01,
    });
    let clock = Clock::start();
    let mut bench = ImuBench::start(MockBus::new(chip), &config, clock);
    let mut core = Core::new(&config, Field::competition().start_pose()).expect("a core");
    let deadline = Instant::now() + Duration::from_secs(5);
    let mut fed = 0;
    let measured = loop {
        assert!(Instant::now() < deadline, "no bias after {fed} samples");
        bench.wait_for(Duration::from_secs(1), "a sample", |b| {
            b.samples().len() > fed
        });
        let stamped = bench.samples()[fed].0.clone();
        fed += 1;
        let outputs = core.step(&stamped);
        let bias = outputs.events.iter().find_map(|e| match e {
            Event::GyroBiasMeasured { bias_rad_s } => Some(*bias_rad_s),
            Event::GyroBiasRefused { reason } => panic!("refused: {reason:?}"),
            _ => None,
        });
        if let Some(bias) = bias {
            break bias;
        }
    };
    println!("start-up gyro bias: measured {measured:.5} rad/s, true {bias_z} rad/s");
    assert!((measured - bias_z).abs() < 0.001, "{measured}");
}

#[test]
fn a_bus_glitch_is_ridden_out_and_a_dead_bus_ends_the_imu_thread() {
    let bus = MockBus::new(SimMpu9255::new(5));
    let mut bench = ImuBench::start(bus.clone(), &Config::default(), Clock::start());
    bench.wait_for(Duration::from_secs(2), "samples", |b| {
        b.samples().len() >= 5
    });
    // A glitch: a few failed transfers, fewer than the thread tolerates.
    bus.failures_left
        .store(MAX_FAILED_READS / 2, Ordering::SeqCst);
    bench.wait_for(Duration::from_secs(2), "the glitch", |_| {
        bus.failures_left.load(Ordering::SeqCst) == 0
    });
    let after_glitch = bench.samples().len();
    bench.wait_for(Duration::from_secs(2), "samples after the glitch", |b| {
        b.samples().len() >= after_glitch + 5
    });
    assert_eq!(bus.failed.load(Ordering::SeqCst), MAX_FAILED_READS / 2);
    assert!(
        !bench
            .messages
            .contains(&Message::Link(DeviceKind::Imu, LinkState::Reconnecting))
    );

    // The bus dies: after MAX_FAILED_READS failures in a row the IMU is given up.
    bus.dead.store(true, Ordering::SeqCst);
    bench.wait_for(Duration::from_secs(3), "the IMU given up", |b| {
        b.messages
            .contains(&Message::Link(DeviceKind::Imu, LinkState::Reconnecting))
    });
    let thread = bench.thread.take().expect("the thread");
    let deadline = Instant::now() + Duration::from_secs(2);
    while !thread.is_finished() {
        assert!(Instant::now() < deadline, "the IMU thread did not end");
        let _ = bench.rx.recv_timeout(Duration::from_millis(5));
    }
    thread.join().expect("no panic");
    assert_eq!(
        bus.failed.load(Ordering::SeqCst),
        MAX_FAILED_READS / 2 + MAX_FAILED_READS
    );
}

#[test]
fn a_bus_that_is_not_there_is_named() {
    let Err(message) = imu::open_i2c("/nonexistent/i2c-7", &Default::default()) else {
        panic!("opened a bus that does not exist");
    };
    assert!(message.starts_with("/nonexistent/i2c-7: "), "{message}");
}
