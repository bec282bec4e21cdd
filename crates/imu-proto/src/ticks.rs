//! Unwrapping the device's free-running u16 timer into a monotonic u64 tick count.

/// Seconds per timer tick used by most drivers (6.5536 ms, so the u16 counter wraps about every
/// 429.5 s).
///
/// **Disputed**: one driver reprograms the calculation-cycle EEPROM words and uses 10 ms. The
/// value in force belongs in [`DeviceParams::tick_period_s`](crate::device::DeviceParams), and
/// the daemon should estimate it against the host clock.
pub const DEFAULT_TICK_PERIOD_S: f64 = 6.5536e-3;

/// Number of distinct tick values: one wrap adds this much.
pub const TICKS_PER_WRAP: u64 = 1 << 16;

/// Turns successive u16 tick readings into a monotonic u64 count.
///
/// Each time a reading is smaller than the previous one, the counter is assumed to have wrapped
/// once and [`TICKS_PER_WRAP`] (65536, **not** 65535: one driver's known off-by-one) is added.
/// The first reading is returned unchanged. A reading equal to the previous one is not a wrap.
///
/// The unwrapper cannot see more than one wrap between two readings (gaps longer than ~429 s at
/// the default period) nor tell a device reset from a wrap; the caller, who knows the host-clock
/// time between readings, has to catch those.
///
/// ```
/// use imu_proto::ticks::TickUnwrapper;
/// let mut t = TickUnwrapper::new();
/// assert_eq!(t.unwrap(65_530), 65_530);
/// assert_eq!(t.unwrap(4), 65_536 + 4);
/// assert_eq!(t.wraps(), 1);
/// ```
///
/// A counter of another width (a MIP unit's u32 internal timestamp) unwraps the same way with
/// [`TickUnwrapper::with_bits`] and [`TickUnwrapper::unwrap_wide`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TickUnwrapper {
    last_ticks: Option<u64>,
    wraps: u64,
    /// Distinct counter values (0: a 64-bit counter, which never wraps here).
    modulus: u64,
}

impl Default for TickUnwrapper {
    fn default() -> Self {
        Self::new()
    }
}

impl TickUnwrapper {
    /// A fresh unwrapper of the GX1's 16-bit counter that has seen no reading.
    pub const fn new() -> Self {
        Self::with_bits(16)
    }

    /// A fresh unwrapper of a `bits`-wide counter (1..=64).
    pub const fn with_bits(bits: u32) -> Self {
        Self {
            last_ticks: None,
            wraps: 0,
            modulus: if bits >= 64 { 0 } else { 1 << bits },
        }
    }

    /// Feeds the next reading and returns the unwrapped tick count.
    pub fn unwrap(&mut self, ticks: u16) -> u64 {
        self.unwrap_wide(u64::from(ticks))
    }

    /// [`Self::unwrap`] for a counter of the width given to [`Self::with_bits`].
    pub fn unwrap_wide(&mut self, ticks: u64) -> u64 {
        if let Some(last) = self.last_ticks
            && ticks < last
            && self.modulus != 0
        {
            self.wraps += 1;
        }
        self.last_ticks = Some(ticks);
        self.wraps.wrapping_mul(self.modulus).wrapping_add(ticks)
    }

    /// Number of wraps seen so far.
    pub const fn wraps(&self) -> u64 {
        self.wraps
    }

    /// The last reading fed, if any.
    pub const fn last_ticks(&self) -> Option<u64> {
        self.last_ticks
    }

    /// Forgets everything, e.g. after the device was restarted (the width stays).
    pub fn reset(&mut self) {
        *self = Self {
            last_ticks: None,
            wraps: 0,
            modulus: self.modulus,
        };
    }
}

/// Converts a tick count to seconds with the given tick period.
pub fn ticks_to_s(ticks: u64, tick_period_s: f64) -> f64 {
    ticks as f64 * tick_period_s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_value_is_returned_as_is() {
        let mut t = TickUnwrapper::new();
        assert_eq!(t.last_ticks(), None);
        assert_eq!(t.unwrap(1234), 1234);
        assert_eq!(t.wraps(), 0);
    }

    #[test]
    fn several_wraps_add_65536_each() {
        let mut t = TickUnwrapper::new();
        let readings = [60_000u16, 65_535, 0, 30_000, 65_535, 1, 1, 2, 65_000, 10];
        let expected = [
            60_000u64,
            65_535,
            65_536,
            65_536 + 30_000,
            65_536 + 65_535,
            2 * 65_536 + 1,
            2 * 65_536 + 1, // equal reading: no wrap
            2 * 65_536 + 2,
            2 * 65_536 + 65_000,
            3 * 65_536 + 10,
        ];
        let got: Vec<u64> = readings.iter().map(|&r| t.unwrap(r)).collect();
        assert_eq!(got, expected);
        assert_eq!(t.wraps(), 3);
    }

    #[test]
    fn wrap_is_65536_not_65535() {
        // 65535 -> 0 is ONE tick later. The buggy driver's +65535 would make these equal.
        let mut t = TickUnwrapper::new();
        let before = t.unwrap(65_535);
        let after = t.unwrap(0);
        assert_eq!(after - before, 1);
        assert_eq!(after, 65_536);
        assert_ne!(after, 65_535, "off-by-one wrap constant");
    }

    #[test]
    fn steady_stream_is_monotonic_and_exact() {
        // A counter advancing 1000 ticks per reading from 0 for 10 wraps is recovered exactly.
        let mut t = TickUnwrapper::new();
        for i in 0..=655u64 {
            let true_ticks = i * 1000;
            assert_eq!(t.unwrap((true_ticks % TICKS_PER_WRAP) as u16), true_ticks);
        }
        assert_eq!(t.wraps(), 655_000 / 65_536);
        t.reset();
        assert_eq!(t, TickUnwrapper::new());
    }

    #[test]
    fn a_32_bit_counter_wraps_at_2_pow_32() {
        let mut t = TickUnwrapper::with_bits(32);
        assert_eq!(
            t.unwrap_wide(u64::from(u32::MAX) - 10),
            u64::from(u32::MAX) - 10
        );
        assert_eq!(t.unwrap_wide(52), (1 << 32) + 52);
        assert_eq!(t.wraps(), 1);
        let mut wide = TickUnwrapper::with_bits(64);
        assert_eq!(wide.unwrap_wide(u64::MAX), u64::MAX);
        assert_eq!(wide.unwrap_wide(3), 3, "a 64-bit counter never wraps");
    }

    #[test]
    fn seconds() {
        assert!((ticks_to_s(65_536, DEFAULT_TICK_PERIOD_S) - 429.496_729_6).abs() < 1e-9);
        assert!((ticks_to_s(100, 0.01) - 1.0).abs() < 1e-12);
    }
}
