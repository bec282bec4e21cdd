//! A scripted peer for the drivers' tests: the simulator's virtual device (the same codec and
//! command semantics as `imu-sim`'s pty link) answering what a driver writes, with faults
//! injected per answer (late, corrupt, missing, duplicated), and a loop that runs driver and
//! peer on a simulated clock. Nothing sleeps: time jumps to the next deadline, so a start-up
//! with seconds of time-outs runs in microseconds.

use std::time::{Duration, Instant};

use imu_proto::DeviceProtocol;
use imu_sim::virtual_device::Request;
use imu_sim::{DeviceCore, Scenario, VirtualDevice};

use super::{DeviceIdentity, Driver, DriverEvent, FrameSlot};
use crate::pipeline::{DeviceReading, Pipeline, SessionSpec, Sinks, log_rejected};

const SCENARIO: &str = include_str!("../../../config/scenarios/demo.toml");
const TRUTH: &str = imu_model::EXAMPLE_GX1_MODEL_TOML;

/// What happens to one answer of the peer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Fate {
    /// Sent after the device's own delay.
    Deliver,
    /// Sent this much later than that.
    Late(Duration),
    /// One byte of it flipped (a checksum failure).
    Corrupt,
    /// Never sent.
    Missing,
    /// Sent twice.
    Duplicate,
    /// Held back and sent just after the next answer (the two out of order).
    Reordered,
}

/// Decides the fate of the `n`-th answer (from 0) to a request.
pub type Script = Box<dyn FnMut(usize, &Request) -> Fate>;

/// The simulator's device with a script of faults.
pub struct Peer {
    device: VirtualDevice,
    script: Script,
    answers: usize,
    /// An answer held back until the next one is sent.
    held: Option<Vec<u8>>,
    /// Bytes on their way to the host: (arrival, bytes), in arrival order.
    in_flight: Vec<(Instant, Vec<u8>)>,
    /// When the device started streaming, and samples sent since.
    stream: Option<(Instant, u64)>,
    period: Duration,
    origin: Instant,
    /// Every request the device decoded, in order.
    pub requests: Vec<Request>,
    /// Stop answering and streaming altogether (the cable pulled).
    pub silent: bool,
    /// Samples streamed so far.
    pub sent: u64,
}

impl Peer {
    /// A device speaking `protocol` that follows `script`, powered up idle at `origin`.
    pub fn new(protocol: DeviceProtocol, script: Script, origin: Instant) -> Self {
        Self::powered_up(protocol, script, false, origin)
    }

    /// The same, powered up at `origin` idle or, with `streaming`, streaming with no command
    /// (the simulator's `device.power-up-streaming`: a GX1 saved in continuous mode, a MIP
    /// unit saved resumed).
    fn powered_up(
        protocol: DeviceProtocol,
        script: Script,
        streaming: bool,
        origin: Instant,
    ) -> Self {
        Self::powered_up_with(protocol, script, streaming, origin, |_| {})
    }

    /// The same with the demo scenario changed by `edit` first.
    fn powered_up_with(
        protocol: DeviceProtocol,
        script: Script,
        streaming: bool,
        origin: Instant,
        edit: impl FnOnce(&mut Scenario),
    ) -> Self {
        let mut scenario = Scenario::from_toml_str(SCENARIO, "demo").expect("demo scenario");
        scenario.device.power_up_streaming = streaming;
        edit(&mut scenario);
        scenario.set_protocol(protocol, "test").expect("protocol");
        let truth = imu_model::Calibration::from_toml_str(TRUTH, "truth").expect("truth model");
        let core = DeviceCore::new(scenario, truth, 7);
        let period = Duration::from_secs_f64(core.sample_period_s());
        let device = VirtualDevice::new(protocol, core);
        let stream = device.is_streaming().then_some((origin, 0));
        Self {
            device,
            script,
            answers: 0,
            held: None,
            in_flight: Vec::new(),
            stream,
            period,
            origin,
            requests: Vec::new(),
            silent: false,
            sent: 0,
        }
    }

    /// A well-behaved device.
    pub fn clean(protocol: DeviceProtocol, origin: Instant) -> Self {
        Self::new(protocol, Box::new(|_, _| Fate::Deliver), origin)
    }

    /// A well-behaved device that powered up streaming at `origin`, as one set up and saved
    /// with the vendor's tool.
    pub fn streaming(protocol: DeviceProtocol, origin: Instant) -> Self {
        Self::powered_up(protocol, Box::new(|_, _| Fate::Deliver), true, origin)
    }

    /// A well-behaved device powered up streaming, its scenario changed by `edit`.
    pub fn streaming_with(
        protocol: DeviceProtocol,
        origin: Instant,
        edit: impl FnOnce(&mut Scenario),
    ) -> Self {
        Self::powered_up_with(protocol, Box::new(|_, _| Fate::Deliver), true, origin, edit)
    }

    fn t_s(&self, now: Instant) -> f64 {
        (now - self.origin).as_secs_f64()
    }

    fn send(&mut self, at: Instant, bytes: Vec<u8>) {
        let i = self.in_flight.partition_point(|(t, _)| *t <= at);
        self.in_flight.insert(i, (at, bytes));
    }

    /// Bytes the host wrote at `now`.
    pub fn receive(&mut self, bytes: &[u8], now: Instant) {
        if self.silent {
            return;
        }
        self.device.push(bytes);
        while let Some(request) = self.device.next_request() {
            let Ok(request) = request else { continue };
            self.requests.push(request.clone());
            let was_streaming = self.device.is_streaming();
            let answer = self.device.handle(request.clone(), self.t_s(now));
            match (was_streaming, self.device.is_streaming()) {
                (false, true) => self.stream = Some((now, 0)),
                (true, false) => self.stream = None,
                _ => {}
            }
            if answer.bytes.is_empty() {
                continue;
            }
            let at =
                now + Duration::from_secs_f64(answer.delay_s.max(0.0)) + Duration::from_micros(500);
            let fate = (self.script)(self.answers, &request);
            self.answers += 1;
            let mut bytes = answer.bytes;
            match fate {
                Fate::Deliver => self.send(at, bytes),
                Fate::Late(d) => self.send(at + d, bytes),
                Fate::Corrupt => {
                    let last = bytes.len() - 1;
                    bytes[last] ^= 0x5A;
                    self.send(at, bytes);
                }
                Fate::Missing => {}
                Fate::Duplicate => {
                    self.send(at, bytes.clone());
                    self.send(at + Duration::from_millis(1), bytes);
                }
                Fate::Reordered => {
                    self.held = Some(bytes);
                    continue;
                }
            }
            if let Some(held) = self.held.take() {
                self.send(at + Duration::from_millis(1), held);
            }
        }
    }

    /// When the peer next sends something.
    pub fn next_output(&self) -> Option<Instant> {
        if self.silent {
            return None;
        }
        let stream = self.stream.map(|(t0, n)| t0 + self.period * (n as u32 + 1));
        match (self.in_flight.first().map(|(t, _)| *t), stream) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    /// Everything the peer sends at or before `now`.
    pub fn output(&mut self, now: Instant) -> Vec<u8> {
        let mut out = Vec::new();
        if self.silent {
            return out;
        }
        while self.in_flight.first().is_some_and(|(t, _)| *t <= now) {
            out.extend(self.in_flight.remove(0).1);
        }
        while let Some((t0, n)) = self.stream {
            let t = t0 + self.period * (n as u32 + 1);
            if t > now {
                break;
            }
            let t_s = self.t_s(t);
            self.sent += u64::from(self.device.stream_sample(t_s, &mut out).is_some());
            self.stream = Some((t0, n + 1));
        }
        out
    }
}

/// What the driver said, in order.
#[derive(Debug, Default)]
pub struct Seen {
    /// Good frames.
    pub frames: u64,
    /// Frames with a reading, and the readings.
    pub readings: Vec<DeviceReading>,
    /// Temperatures taken.
    pub temperatures: u64,
    /// Rejected byte runs.
    pub rejected: u64,
    /// Sessions set.
    pub sessions: Vec<SessionSpec>,
    /// The identity, once identified.
    pub identity: Option<DeviceIdentity>,
    /// The identity, once start-up is done.
    pub ready: Option<DeviceIdentity>,
    /// Why start-up failed.
    pub failed: Option<String>,
}

/// A driver and a peer on one simulated clock.
pub struct Harness<D: Driver> {
    /// The driver under test.
    pub driver: D,
    /// The peer.
    pub peer: Peer,
    /// The simulated time.
    pub now: Instant,
    /// When the run began.
    pub origin: Instant,
    /// What the driver said.
    pub seen: Seen,
    /// Every write of the driver, with its time.
    pub written: Vec<(Instant, Vec<u8>)>,
    /// The pipeline the events go through, as the session's do (no outputs).
    pub pipeline: Pipeline,
    sinks: Sinks,
}

impl<D: Driver> Harness<D> {
    /// `driver` against `peer`, both from `origin`; the driver's start-up begins now.
    pub fn new(mut driver: D, peer: Peer, origin: Instant) -> Self {
        driver.start(origin);
        let pipeline = Pipeline::new(driver.initial_session(), None);
        Self {
            driver,
            peer,
            now: origin,
            origin,
            seen: Seen::default(),
            written: Vec::new(),
            pipeline,
            sinks: Sinks::default(),
        }
    }

    /// Simulated time since the start.
    pub fn elapsed(&self) -> Duration {
        self.now - self.origin
    }

    /// Host time of now, ns (monotonic and wall alike).
    fn host_ns(&self) -> u64 {
        1_000_000_000_000 + (self.now - self.origin).as_nanos() as u64
    }

    fn take_events(&mut self) {
        let t_ns = self.host_ns();
        let mut slot = FrameSlot::default();
        while let Some(ev) = self.driver.poll_event(&mut slot) {
            match ev {
                DriverEvent::Frame => {
                    self.seen.frames += 1;
                    self.seen.readings.extend(slot.content.reading);
                    self.seen.temperatures += u64::from(slot.content.temperature.is_some());
                    self.pipeline
                        .on_frame(&mut slot, t_ns, t_ns, &mut self.sinks);
                }
                DriverEvent::Rejected {
                    bytes,
                    offset,
                    reason,
                } => {
                    self.seen.rejected += 1;
                    log_rejected(bytes, offset, reason, t_ns, t_ns, &self.sinks);
                }
                DriverEvent::Session(s) => {
                    self.seen.sessions.push(s);
                    self.pipeline.new_session(s);
                }
                DriverEvent::Identified(id) => self.seen.identity = Some(*id),
                DriverEvent::Ready => self.seen.ready = self.seen.identity.clone(),
                DriverEvent::Failed(e) => self.seen.failed = Some(format!("{e:#}")),
            }
        }
        let mut out = Vec::new();
        while self.driver.poll_transmit(&mut out) {}
        if !out.is_empty() {
            self.peer.receive(&out, self.now);
            self.written.push((self.now, out));
        }
    }

    /// Runs until `done` says so or `limit` of simulated time has passed; true if done.
    pub fn run_until(&mut self, limit: Duration, mut done: impl FnMut(&Seen) -> bool) -> bool {
        let end = self.now + limit;
        for _ in 0..10_000_000 {
            self.take_events();
            if done(&self.seen) {
                return true;
            }
            let next = match (self.driver.poll_timeout(), self.peer.next_output()) {
                (Some(a), Some(b)) => a.min(b),
                (a, b) => match a.or(b) {
                    Some(t) => t,
                    None => return false,
                },
            };
            if next > end {
                self.now = end;
                return false;
            }
            self.now = self.now.max(next);
            let bytes = self.peer.output(self.now);
            if !bytes.is_empty() {
                self.driver.handle_input(&bytes, self.now);
            }
            if self.driver.poll_timeout().is_some_and(|t| t <= self.now) {
                self.driver.handle_timeout(self.now);
            }
        }
        panic!("the driver made no progress in ten million steps");
    }

    /// Starts the driver's start-up again (a reconnect), with what was seen forgotten.
    pub fn restart(&mut self) {
        self.seen = Seen::default();
        self.driver.start(self.now);
    }

    /// Runs until start-up is done or failed (at most a minute of simulated time).
    pub fn start_up(&mut self) {
        let done = self.run_until(Duration::from_secs(60), |s| {
            s.ready.is_some() || s.failed.is_some()
        });
        assert!(done, "start-up neither finished nor failed in a minute");
    }
}
