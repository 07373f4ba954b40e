//! A small deterministic random number generator for the simulator.
//!
//! xoshiro256++ (Blackman & Vigna, 2019) seeded through SplitMix64, with Box–Muller normal
//! samples. Written here rather than taken from `rand` so that a seed gives the same run on
//! every platform and every future version of the project: the simulator's logs are compared
//! byte for byte.

/// Deterministic pseudo-random source. Each simulated device owns its own stream
/// ([`SimRng::fork`]), so adding a device does not change the noise another device sees.
#[derive(Clone, Debug)]
pub struct SimRng {
    state: [u64; 4],
    spare_normal: Option<f64>,
}

fn splitmix64(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

impl SimRng {
    /// A generator whose whole sequence is determined by `seed`.
    pub fn new(seed: u64) -> Self {
        let mut sm = seed;
        Self {
            state: [
                splitmix64(&mut sm),
                splitmix64(&mut sm),
                splitmix64(&mut sm),
                splitmix64(&mut sm),
            ],
            spare_normal: None,
        }
    }

    /// An independent generator for a named sub-system, derived from this one's seed
    /// material without advancing it.
    pub fn fork(&self, stream: &str) -> Self {
        let mut h = self.state[0] ^ self.state[3].rotate_left(17);
        for byte in stream.bytes() {
            h = (h ^ u64::from(byte)).wrapping_mul(0x0100_0000_01B3);
        }
        Self::new(h)
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        let s = &mut self.state;
        let result = s[0].wrapping_add(s[3]).rotate_left(23).wrapping_add(s[0]);
        let t = s[1] << 17;
        s[2] ^= s[0];
        s[3] ^= s[1];
        s[1] ^= s[2];
        s[0] ^= s[3];
        s[2] ^= t;
        s[3] = s[3].rotate_left(45);
        result
    }

    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Uniform in [low, high).
    pub fn uniform_in(&mut self, low: f64, high: f64) -> f64 {
        low + (high - low) * self.uniform()
    }

    /// True with probability `p`.
    pub fn chance(&mut self, p: f64) -> bool {
        self.uniform() < p
    }

    /// A standard normal sample (Box–Muller, both values used).
    pub fn standard_normal(&mut self) -> f64 {
        if let Some(z) = self.spare_normal.take() {
            return z;
        }
        let u1 = 1.0 - self.uniform(); // (0, 1]: ln is finite
        let u2 = self.uniform();
        let radius = (-2.0 * u1.ln()).sqrt();
        let angle = std::f64::consts::TAU * u2;
        self.spare_normal = Some(radius * angle.sin());
        radius * angle.cos()
    }

    /// A normal sample with mean 0 and standard deviation `sigma`.
    pub fn normal(&mut self, sigma: f64) -> f64 {
        sigma * self.standard_normal()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_seed_same_sequence_different_seed_different_sequence() {
        let a: Vec<u64> = (0..8)
            .scan(SimRng::new(7), |r, _| Some(r.next_u64()))
            .collect();
        let b: Vec<u64> = (0..8)
            .scan(SimRng::new(7), |r, _| Some(r.next_u64()))
            .collect();
        let c: Vec<u64> = (0..8)
            .scan(SimRng::new(8), |r, _| Some(r.next_u64()))
            .collect();
        assert_eq!(a, b);
        assert_ne!(a, c);
    }

    #[test]
    fn forks_are_independent_of_each_other_and_of_the_parent() {
        let parent = SimRng::new(1);
        let mut lidar = parent.fork("lidar");
        let mut imu = parent.fork("imu");
        assert_ne!(lidar.next_u64(), imu.next_u64());
        assert_eq!(
            parent.fork("lidar").next_u64(),
            SimRng::new(1).fork("lidar").next_u64()
        );
    }

    #[test]
    fn normal_samples_have_the_requested_moments() {
        let mut rng = SimRng::new(42);
        let n = 200_000;
        let samples: Vec<f64> = (0..n).map(|_| rng.normal(2.0)).collect();
        let mean = samples.iter().sum::<f64>() / n as f64;
        let var = samples.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n as f64;
        assert!(mean.abs() < 0.02, "mean {mean}");
        assert!((var.sqrt() - 2.0).abs() < 0.02, "sigma {}", var.sqrt());
    }

    #[test]
    fn uniform_stays_in_range() {
        let mut rng = SimRng::new(3);
        for _ in 0..10_000 {
            let u = rng.uniform_in(-1.0, 2.0);
            assert!((-1.0..2.0).contains(&u));
        }
    }
}
