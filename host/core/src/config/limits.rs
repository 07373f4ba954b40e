//! Physical facts that bound several configuration keys, each with its source. The bounds
//! say what a real robot on a real floor can be, so that no accepted value can exhaust
//! memory, overflow arithmetic or overload a link, and no value a team might really use is
//! refused.

/// The round's slot, s: each team gets one 10-minute slot per round (competition.md §2), so
/// no wait, timeout or delay within a round is meaningfully longer.
pub(crate) const ROUND_SLOT_S: f64 = 600.0;

/// The longest straight line on the floor, m: the printed floor is 1.682 × 1.189 m
/// (competition.md §1.1), diagonal 2.06 m, and the rules allow +10 % (2.27 m); rounded up.
pub(crate) const FLOOR_DIAGONAL_M: f64 = 2.3;

/// The longest straight run in front of a slot, m: machine A's output (x = −0.145 m at the
/// pick pose) and machine B's input face each other in the y = 0 row, 0.535 m apart between
/// their divider tips (x = ±0.2675 m, `field::stations`), so the 0.30 m robot can move
/// 0.26 m straight out of one before its back reaches the other.
pub(crate) const STRAIGHT_RUN_M: f64 = 0.26;

/// The host's reference period, µs: it sends `G H I J L U` on its own 50 Hz tick
/// (`ratf_sim::devices::HOST_TICK_PERIOD_US`, `ratf_host::devices::HOST_TICK_PERIOD_US`).
pub(crate) const HOST_REFERENCE_PERIOD_US: u32 = 20_000;

/// Bytes of one host → Mega reference batch: `G H I J L U` and the checksum frame `Z`, 9
/// bytes each (protocol/README.md §2–3; [`crate::drivers::mega_link::REFERENCE_BATCH_FRAMES`]).
pub(crate) const REFERENCE_BATCH_BYTES: u32 = ((crate::drivers::mega_link::REFERENCE_BATCH_FRAMES
    + 1)
    * ratf_protocol::channels::FRAME_LEN) as u32;

/// The IMU's read period, µs: the driver configures 200 Hz (`drivers::imu`, sample-rate
/// divider 4) and the simulator reads it at that rate.
pub(crate) const IMU_READ_PERIOD_US: u32 = 5_000;

/// Bits on a UART line per byte, 8N1: start, 8 data, stop.
pub(crate) const BITS_PER_BYTE: f64 = 10.0;

/// The highest battery voltage the motor drivers take, V: the Adafruit Motor Shield V2's
/// TB6612 H-bridges are rated 4.5–13.5 V (hardware/README.md, item 2); a full 3S LiPo is
/// 12.6 V.
pub(crate) const MOTOR_SUPPLY_MAX_V: f64 = 13.5;

/// Encoder edges per second per wheel the Mega counts without loss: every edge counted at
/// 38 000 edges/s on all four encoders at once, losses from 40 000 (firmware-mega/README.md,
/// "Encoder counting in simavr").
pub(crate) const MAX_ENCODER_EDGES_PER_S: f64 = 38_000.0;

/// Fraction of a serial line a steady stream may fill: the rest absorbs the bytes' delivery
/// by the USB bridges in 1 ms frames, the clocks' baud-rate error (115 200 from 16 MHz is
/// 2.1 % off) and jitter, so that queues stay short instead of growing.
pub(crate) const MEGA_LINK_MAX_LOAD: f64 = 0.8;

/// Fraction of the X4's line its scan stream may fill: the X4 itself fills 88 % of its
/// 128 000 baud at its 5 kHz ranging rate (real-world-errors.md §1), so the margin left is
/// smaller than the Mega's, and what exceeds it would queue without end.
pub(crate) const LIDAR_LINK_MAX_LOAD: f64 = 0.95;
