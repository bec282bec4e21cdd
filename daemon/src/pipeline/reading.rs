//! What a driver hands the pipeline, whatever the device speaks: one [`DeviceReading`] per data
//! frame, and per session a [`SessionSpec`] (its clock, its acquisition, the device's scale words
//! if it has any). Nothing here knows a protocol: the drivers (`crate::drivers`) fill these in.

use imu_bus::recording::SampleFrame;
use imu_model::Measured;

use super::loss::TickKind;

/// One data sample as the device sent it: what the shared steps need.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DeviceReading {
    /// The device's sample clock, unwrapped, in ticks of the session's timebase.
    pub ticks_unwrapped: u64,
    /// Its low 16 bits as sent.
    pub ticks: u16,
    /// The counts, for a device that sends counts.
    pub counts: Option<Counts>,
    /// The device's own reading in SI (its scale words applied, or the SI values it sends).
    pub measured: Measured,
    /// A channel sat at the end of its range.
    pub saturated: bool,
    /// The device's code for the kind of data (a reply code, a descriptor set).
    pub command: u8,
    /// The unit's own compensated reading (its factory calibration and its bias estimates
    /// applied), when it sends one beside the uncompensated `measured` that imud's calibration
    /// corrects (Xsens, VectorNav); recorded beside the raw, never corrected again.
    pub compensated: Option<Measured>,
    /// The GNSS time the unit attached to this sample, if it sends one (valid or not).
    pub gnss: Option<imu_proto::gnss_time::GnssTime>,
}

/// The counts of one data frame, widened to i32.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Counts {
    /// Accelerometer counts.
    pub accel: [i32; 3],
    /// Gyro counts.
    pub gyro: [i32; 3],
    /// Magnetometer counts.
    pub mag: [i32; 3],
    /// Signed scaled counts rather than raw ADC bits.
    pub scaled: bool,
}

/// Which scale words are the configured fallbacks (the device's could not be read).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct GainFallback {
    /// The accelerometer's is the fallback.
    pub accel: bool,
    /// The gyro's is the fallback.
    pub gyro: bool,
    /// The magnetometer's is the fallback.
    pub mag: bool,
}

impl GainFallback {
    /// All three are fallbacks (before the device answered).
    pub const ALL: Self = Self {
        accel: true,
        gyro: true,
        mag: true,
    };
    /// None is: all three were read from the device.
    pub const NONE: Self = Self {
        accel: false,
        gyro: false,
        mag: false,
    };

    /// True if any is a fallback.
    pub fn any(self) -> bool {
        self.accel || self.gyro || self.mag
    }

    /// Bit mask for the status: 1 accel, 2 gyro, 4 mag.
    pub fn mask(self) -> u8 {
        u8::from(self.accel) | u8::from(self.gyro) << 1 | u8::from(self.mag) << 2
    }
}

/// The device's scale words (GainScales) in force and which of them are fallbacks; all zero
/// for a device that sends SI values.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Gains {
    /// Accelerometer GainScale.
    pub accel: u16,
    /// Gyro GainScale.
    pub gyro: u16,
    /// Magnetometer GainScale.
    pub mag: u16,
    /// Which of them are the configured fallbacks.
    pub fallback: GainFallback,
}

impl Gains {
    /// A device without scale words (it sends SI values): all zero, none a fallback.
    pub const NOT_APPLICABLE: Self = Self {
        accel: 0,
        gyro: 0,
        mag: 0,
        fallback: GainFallback::NONE,
    };

    /// The recording metadata that states the gains in force and where each came from.
    pub fn metadata(&self) -> [(String, String); 7] {
        let source = |fallback: bool| if fallback { "fallback" } else { "device" };
        [
            ("gain-scale-accel".into(), self.accel.to_string()),
            ("gain-scale-gyro".into(), self.gyro.to_string()),
            ("gain-scale-mag".into(), self.mag.to_string()),
            (
                "gain-scale-accel-source".into(),
                source(self.fallback.accel).into(),
            ),
            (
                "gain-scale-gyro-source".into(),
                source(self.fallback.gyro).into(),
            ),
            (
                "gain-scale-mag-source".into(),
                source(self.fallback.mag).into(),
            ),
            ("gains-are-fallback".into(), self.fallback.any().to_string()),
        ]
    }
}

/// How long one tick of a device clock is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TickLength {
    /// A period in seconds that is no whole number of ns (a configured, disputed period).
    Seconds(f64),
    /// A whole number of ns, so device times are exact integers.
    WholeNs(u64),
}

/// A session's device clock: how long a tick is, how wide the counter is, and how ticks
/// compare with the sample interval.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Timebase {
    /// One tick.
    pub tick: TickLength,
    /// Coarse (about a tick a sample) or fine (many ticks a sample).
    pub kind: TickKind,
}

impl Timebase {
    /// Seconds per tick (nominal: the clock fit measures the device's oscillator).
    pub fn tick_period_s(self) -> f64 {
        match self.tick {
            TickLength::Seconds(s) => s,
            TickLength::WholeNs(ns) => ns as f64 * 1e-9,
        }
    }

    /// Device time of `ticks`, ns (exact integers where a tick is a whole number of ns).
    pub fn device_ns(self, ticks: u64) -> u64 {
        match self.tick {
            TickLength::Seconds(s) => (ticks as f64 * s * 1e9) as u64,
            TickLength::WholeNs(ns) => ticks.saturating_mul(ns),
        }
    }
}

/// Who paces the samples of a session.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Acquisition {
    /// The device streams at its own rate: its clock accounts for losses.
    Streaming,
    /// The host polls each sample at `rate_hz`: the intervals are the host's, no losses are
    /// counted and the data rate is the poll rate.
    Polled {
        /// Polls per second.
        rate_hz: f64,
    },
}

/// How a temperature the device sends is recorded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TemperatureCadence {
    /// A reading of its own (a polled temperature): every one is recorded.
    Each,
    /// It comes with every sample: recorded once a second.
    WithSamples,
}

/// What the pipeline needs to know of a device session before its first sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SessionSpec {
    /// The device's scale words in force (or [`Gains::NOT_APPLICABLE`]).
    pub gains: Gains,
    /// The sample clock.
    pub timebase: Timebase,
    /// Who paces the samples.
    pub acquisition: Acquisition,
    /// The status's `protocol` byte (`imu_bus::sample::device_protocol`).
    pub status_protocol: u8,
    /// Start-up set up and read back the device; false for a passive unit (asked nothing,
    /// its stream taken as it is), which the status says (`configuration_unverified`).
    pub configuration_verified: bool,
}

/// What one good frame from the device carried, beyond its bytes.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FrameContent {
    /// A data sample.
    pub reading: Option<DeviceReading>,
    /// A temperature, deg C, and how it is recorded.
    pub temperature: Option<(f64, TemperatureCadence)>,
    /// A data frame that made no sample (undecodable, or without its clock or data fields).
    pub unusable: bool,
    /// Data fields the codec skipped (unknown descriptors, unexpected sizes).
    pub fields_skipped: u32,
}

/// Where a driver puts each good frame it decodes: owned by whoever runs the driver and reused
/// frame after frame, so the frame's bytes and what it carried are written in place once and
/// read by the pipeline in place, not moved through every event on the way (a frame with its
/// reading is some 300 bytes; moving it from driver to pipeline three times cost a quarter of
/// the decode stage).
#[derive(Debug, Clone, Default)]
pub struct FrameSlot {
    /// The frame's bytes and stream offset.
    pub frame: SampleFrame,
    /// What it carried (nothing while it is only logged: the start-up's replies).
    pub content: FrameContent,
}

impl FrameSlot {
    /// Puts a frame of `bytes` at stream `offset` in the slot (no allocation: a frame fits the
    /// slot's inline buffer); its content is set apart, in place.
    pub fn set_frame(&mut self, bytes: &[u8], offset: u64) {
        self.frame.stream_offset = offset;
        self.frame.bytes.clear();
        self.frame.bytes.extend_from_slice(bytes);
    }
}
