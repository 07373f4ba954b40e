//! A compact histogram of the core's latencies (µs), so a long soak can pool many rounds'
//! latencies into one percentile per stretch of time without keeping every sample: the
//! p99 of one round (about 2 500 inputs, its 25th-largest) swings with a single busy
//! moment of the machine, the p99 of ten minutes of rounds (about 30 000) does not.

/// Width of a bucket, µs: 10, under 2 % of the ~600 µs p99 a round has on the
/// development machine, so a 20 % drift is read with room to spare.
pub const BUCKET_US: u32 = 10;

/// Samples above this many µs count in the top bucket (1 s: far above any latency the
/// core can have and still run; it bounds the histogram's size to 400 KB).
pub const TOP_US: u32 = 1_000_000;

/// Counts of latencies per [`BUCKET_US`]-wide bucket, dense from the lowest occupied bucket
/// to the highest.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct LatencyHistogram {
    first_bucket: u32,
    counts: Vec<u32>,
}

fn bucket_of(sample_us: u32) -> u32 {
    sample_us.min(TOP_US) / BUCKET_US
}

impl LatencyHistogram {
    /// The histogram of `samples_us`.
    pub fn of(samples_us: &[u32]) -> Self {
        let mut histogram = Self::default();
        for &sample in samples_us {
            histogram.add_to_bucket(bucket_of(sample), 1);
        }
        histogram
    }

    fn add_to_bucket(&mut self, bucket: u32, count: u32) {
        if self.counts.is_empty() {
            self.first_bucket = bucket;
        } else if bucket < self.first_bucket {
            let grow = (self.first_bucket - bucket) as usize;
            self.counts.splice(0..0, std::iter::repeat_n(0, grow));
            self.first_bucket = bucket;
        }
        let index = (bucket - self.first_bucket) as usize;
        if index >= self.counts.len() {
            self.counts.resize(index + 1, 0);
        }
        self.counts[index] = self.counts[index].saturating_add(count);
    }

    /// Pool `other`'s samples into this one.
    pub fn merge(&mut self, other: &Self) {
        for (offset, &count) in other.counts.iter().enumerate() {
            if count > 0 {
                self.add_to_bucket(other.first_bucket + offset as u32, count);
            }
        }
    }

    /// Samples counted.
    pub fn count(&self) -> u64 {
        self.counts.iter().map(|&c| u64::from(c)).sum()
    }

    /// The `q`-quantile (0 < q ≤ 1) as the upper edge of its bucket, µs: the sample of rank
    /// ⌈q·n⌉ (as [`super::run::Latency::of`] ranks) is below it by less than
    /// [`BUCKET_US`]. 0 when empty.
    pub fn quantile_us(&self, q: f64) -> u32 {
        let n = self.count();
        if n == 0 {
            return 0;
        }
        let rank = ((q * n as f64).ceil() as u64).clamp(1, n);
        let mut seen = 0u64;
        for (offset, &count) in self.counts.iter().enumerate() {
            seen += u64::from(count);
            if seen >= rank {
                return (self.first_bucket + offset as u32 + 1) * BUCKET_US;
            }
        }
        (self.first_bucket + self.counts.len() as u32) * BUCKET_US
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::apps::run::Latency;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn a_quantile_is_the_exact_one_rounded_up_to_its_bucket(
            samples in prop::collection::vec(0u32..50_000, 1..400),
        ) {
            let exact = Latency::of(&samples);
            let histogram = LatencyHistogram::of(&samples);
            prop_assert_eq!(histogram.count(), samples.len() as u64);
            for (q, want) in [(0.5, exact.p50_us), (0.99, exact.p99_us), (1.0, exact.max_us)] {
                let got = histogram.quantile_us(q);
                prop_assert!(want < got && got <= want + BUCKET_US, "q {}: {} for {}", q, got, want);
            }
        }

        #[test]
        fn merging_pools_the_samples(
            a in prop::collection::vec(0u32..50_000, 0..200),
            b in prop::collection::vec(0u32..50_000, 0..200),
        ) {
            let mut merged = LatencyHistogram::of(&a);
            merged.merge(&LatencyHistogram::of(&b));
            let pooled: Vec<u32> = a.iter().chain(&b).copied().collect();
            prop_assert_eq!(merged, LatencyHistogram::of(&pooled));
        }
    }

    #[test]
    fn an_empty_histogram_has_no_quantile_and_outliers_land_in_the_top_bucket() {
        assert_eq!(LatencyHistogram::default().quantile_us(0.99), 0);
        let histogram = LatencyHistogram::of(&[500, u32::MAX]);
        assert_eq!(histogram.quantile_us(1.0), TOP_US + BUCKET_US);
        assert_eq!(histogram.quantile_us(0.5), 510);
    }
}
