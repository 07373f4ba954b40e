//! Wall-clock pacing for a device set that runs faster than time (the simulated world), so
//! a person can watch a round in the HMI: `ratf sim --hmi ADDR --realtime`.

use std::time::{Duration, Instant};

use ratf_core::field::geometry::Pose2;
use ratf_core::runtime::{Devices, Outputs, Stamped};

/// `devices`, each input held back until the wall clock reaches its time (µs after the
/// wrapper was made, scaled by the speed), or passed at once when pacing is off.
#[derive(Debug)]
pub struct Paced<D> {
    devices: D,
    /// Robot seconds per wall second; `None`: as fast as the devices go.
    speed: Option<f64>,
    epoch: Instant,
}

impl<D> Paced<D> {
    /// `devices` at `speed` × real time (`Some(1.0)`: real time), or unpaced with `None`.
    /// A speed that is not a positive finite number means unpaced.
    pub fn new(devices: D, speed: Option<f64>) -> Self {
        Self {
            devices,
            speed: speed.filter(|s| s.is_finite() && *s > 0.0),
            epoch: Instant::now(),
        }
    }

    /// The wrapped devices.
    pub fn inner(&self) -> &D {
        &self.devices
    }

    /// The wrapped devices, mutably.
    pub fn inner_mut(&mut self) -> &mut D {
        &mut self.devices
    }

    /// The wall-clock instant at which an input stamped `time_us` is due.
    fn due(&self, time_us: u64, speed: f64) -> Instant {
        self.epoch + Duration::from_secs_f64(time_us as f64 * 1e-6 / speed)
    }
}

impl<D: Devices> Devices for Paced<D> {
    type Error = D::Error;

    fn next_input(&mut self) -> Result<Option<Stamped>, D::Error> {
        let input = self.devices.next_input()?;
        if let (Some(input), Some(speed)) = (&input, self.speed) {
            let due = self.due(input.time.as_us(), speed);
            let now = Instant::now();
            if due > now {
                std::thread::sleep(due - now);
            }
        }
        Ok(input)
    }

    fn apply(&mut self, input: &Stamped, outputs: &Outputs) -> Result<(), D::Error> {
        self.devices.apply(input, outputs)
    }

    fn ground_truth(&self) -> Option<Pose2> {
        self.devices.ground_truth()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ratf_core::runtime::{Input, Timestamp};

    /// Inputs at the given times, then nothing.
    struct Times(Vec<u64>);

    impl Devices for Times {
        type Error = std::convert::Infallible;
        fn next_input(&mut self) -> Result<Option<Stamped>, Self::Error> {
            Ok((!self.0.is_empty())
                .then(|| Stamped::new(Timestamp::from_us(self.0.remove(0)), Input::HostTick)))
        }
        fn apply(&mut self, _: &Stamped, _: &Outputs) -> Result<(), Self::Error> {
            Ok(())
        }
    }

    #[test]
    fn a_paced_input_is_not_handed_out_before_its_time() {
        let mut paced = Paced::new(Times(vec![0, 30_000]), Some(1.0));
        let epoch = paced.epoch;
        let Ok(first) = paced.next_input();
        assert_eq!(first.map(|s| s.time.as_us()), Some(0));
        let Ok(second) = paced.next_input();
        assert_eq!(second.map(|s| s.time.as_us()), Some(30_000));
        // Monotonic lower bound only: a loaded machine may be later, never earlier.
        assert!(epoch.elapsed() >= Duration::from_millis(30));
        let Ok(end) = paced.next_input();
        assert!(end.is_none());
    }

    #[test]
    fn a_speed_that_is_not_positive_means_unpaced() {
        for speed in [None, Some(0.0), Some(-1.0), Some(f64::NAN)] {
            assert!(
                Paced::new(Times(vec![]), speed).speed.is_none(),
                "{speed:?}"
            );
        }
    }
}
