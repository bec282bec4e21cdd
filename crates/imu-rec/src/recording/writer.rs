//! The writer thread: the MCAP file it writes (counted bytes, rotation, flushes), each log
//! record turned into messages, and what it reports back.

use super::*;

pub(super) fn stats_of(shared: &Shared) -> RecorderStats {
    let load = |a: &AtomicU64| a.load(Ordering::Relaxed);
    RecorderStats {
        written: load(&shared.written),
        flushed: load(&shared.flushed),
        dropped_queue_full: load(&shared.dropped_queue_full),
        dropped_not_logging: load(&shared.dropped_not_logging),
        files_started: load(&shared.files_started),
        bytes_written: load(&shared.bytes_written),
        logging: shared.logging.load(Ordering::Relaxed),
        last_error: lock(&shared.last_error).clone(),
        current_file: lock(&shared.current_file).clone(),
    }
}

pub(super) fn upsert(
    list: &mut Vec<(String, BTreeMap<String, String>)>,
    name: String,
    map: BTreeMap<String, String>,
) {
    match list.iter_mut().find(|(n, _)| *n == name) {
        Some(entry) => entry.1 = map,
        None => list.push((name, map)),
    }
}

/// An error and its causes on one line (`a: b: c`).
pub(super) fn error_chain(e: &dyn std::error::Error) -> String {
    let mut s = e.to_string();
    let mut cause = e.source();
    while let Some(c) = cause {
        s.push_str(": ");
        s.push_str(&c.to_string());
        cause = c.source();
    }
    s
}

/// Counts what reaches the sink: the file size is the furthest byte written.
pub(super) struct CountingSink {
    pub(super) inner: Box<dyn RecordingSink>,
    pub(super) pos: u64,
    pub(super) size: u64,
    pub(super) shared: Arc<Shared>,
    pub(super) file_size: Arc<AtomicU64>,
}

impl Write for CountingSink {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let n = self.inner.write(buf)?;
        self.pos += n as u64;
        if self.pos > self.size {
            self.shared
                .bytes_written
                .fetch_add(self.pos - self.size, Ordering::Relaxed);
            self.size = self.pos;
            self.file_size.store(self.size, Ordering::Relaxed);
        }
        Ok(n)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.inner.flush()
    }
}

impl Seek for CountingSink {
    fn seek(&mut self, pos: SeekFrom) -> io::Result<u64> {
        self.pos = self.inner.seek(pos)?;
        Ok(self.pos)
    }
}

pub(super) type McapWriter = mcap::Writer<BufWriter<CountingSink>>;

/// The file being written.
pub(super) struct OpenFile {
    pub(super) path: PathBuf,
    pub(super) mcap: McapWriter,
    pub(super) channel_ids: [u16; CHANNELS.len()],
    pub(super) sequences: [u32; CHANNELS.len()],
    pub(super) file_size: Arc<AtomicU64>,
    pub(super) opened: Instant,
    pub(super) records: u64,
    /// Records written since the last flush.
    pub(super) unflushed_records: u64,
    /// Uncompressed bytes written since the last flush (the open chunk, for size rotation).
    pub(super) unflushed_bytes: u64,
    /// When the oldest unflushed write happened.
    pub(super) dirty_since: Option<Instant>,
}

impl OpenFile {
    pub(super) fn mcap_err(&self, source: mcap::McapError) -> RecordingError {
        RecordingError::Write {
            path: self.path.clone(),
            source,
        }
    }

    pub(super) fn mark_dirty(&mut self) {
        self.dirty_since.get_or_insert_with(Instant::now);
    }

    pub(super) fn write_msg<M: RosMessage>(
        &mut self,
        channel: usize,
        log_time_ns: u64,
        msg: &M,
        scratch: &mut Vec<u8>,
    ) -> Result<(), RecordingError> {
        scratch.clear();
        msg.encode_into(scratch);
        self.sequences[channel] = self.sequences[channel].wrapping_add(1);
        let header = MessageHeader {
            channel_id: self.channel_ids[channel],
            sequence: self.sequences[channel],
            log_time: log_time_ns,
            publish_time: log_time_ns,
        };
        self.mark_dirty();
        // Message record overhead: opcode, length, header fields.
        self.unflushed_bytes += scratch.len() as u64 + 31;
        self.mcap
            .write_to_known_channel(&header, scratch)
            .map_err(|e| self.mcap_err(e))
    }

    pub(super) fn write_metadata(
        &mut self,
        name: &str,
        map: &BTreeMap<String, String>,
    ) -> Result<(), RecordingError> {
        self.mark_dirty();
        self.mcap
            .write_metadata(&mcap::records::Metadata {
                name: name.to_string(),
                metadata: map.clone(),
            })
            .map_err(|e| self.mcap_err(e))
    }

    pub(super) fn flush(&mut self) -> Result<(), RecordingError> {
        self.mcap.flush().map_err(|e| self.mcap_err(e))?;
        self.dirty_since = None;
        self.unflushed_bytes = 0;
        Ok(())
    }

    pub(super) fn size_estimate(&self) -> u64 {
        self.file_size.load(Ordering::Relaxed) + self.unflushed_bytes
    }

    /// Writes the summary and index and flushes the file to the OS.
    pub(super) fn finish(mut self) -> Result<(), RecordingError> {
        self.mcap.finish().map_err(|e| self.mcap_err(e))?;
        let path = self.path.clone();
        let mut sink = self.mcap.into_inner();
        sink.flush()
            .map_err(|source| RecordingError::Close { path, source })
    }
}

/// The writer thread's state.
pub(super) struct WriterThread {
    pub(super) config: RecordingConfig,
    pub(super) shared: Arc<Shared>,
    pub(super) open: SinkOpener,
    pub(super) file: Option<OpenFile>,
    /// Index of the next file name.
    pub(super) next_index: u32,
    /// When not logging: when to try a new file.
    pub(super) retry_at: Option<Instant>,
    pub(super) noise: Option<ImuNoiseVariances>,
    /// The calibration in force, as metadata for every new file.
    pub(super) calibration: Option<BTreeMap<String, String>>,
    /// Host wall time of the last record handled, ns: when a file starts on a synthetic clock
    /// ([`RecordingConfig::synthetic_start_wall_ns`]).
    pub(super) last_wall_ns: Option<u64>,
    pub(super) scratch: Vec<u8>,
}

/// Records taken from the queue at most between two housekeeping passes.
const BATCH_RECORDS: usize = 4096;
/// The writer's pause after each pass, so records are taken in batches.
const BATCH_PAUSE: Duration = Duration::from_millis(2);

impl WriterThread {
    pub(super) fn run(mut self, rx: Receiver<LogRecord>) -> Result<(), RecordingError> {
        loop {
            let mut batch = 0;
            match rx.recv_timeout(self.next_wakeup()) {
                Ok(record) => {
                    self.handle(record);
                    // What else is queued, before the housekeeping (one metadata lock and clock
                    // read per batch, not per record; bounded, so flushes are never starved).
                    for record in rx.try_iter().take(BATCH_RECORDS) {
                        self.handle(record);
                        batch += 1;
                    }
                }
                Err(RecvTimeoutError::Timeout) => {}
                // Every queued record has been received: the recorder is finishing.
                Err(RecvTimeoutError::Disconnected) => break,
            }
            self.housekeeping();
            // The queue kept up: let records gather, since at the daemon's rates a wake-up per
            // frame (three or four records) costs more than writing them (imud at 1 kHz,
            // BENCHMARKS.md). Behind, go straight on.
            if batch < BATCH_RECORDS {
                std::thread::sleep(BATCH_PAUSE);
            }
        }
        self.write_pending_metadata();
        let result = match self.file.take() {
            Some(file) => {
                let path = file.path.clone();
                let unflushed = file.unflushed_records;
                let result = file.finish();
                match &result {
                    Ok(()) => {
                        self.shared.flushed.fetch_add(unflushed, Ordering::Relaxed);
                        tracing::info!(path = %path.display(), "recording finished");
                    }
                    Err(e) => {
                        self.count_lost(unflushed);
                        self.report_error(e);
                    }
                }
                result
            }
            None => Ok(()),
        };
        self.shared.logging.store(false, Ordering::Relaxed);
        *lock(&self.shared.current_file) = None;
        result
    }

    pub(super) fn next_wakeup(&self) -> Duration {
        let now = Instant::now();
        let mut wait = self.config.flush_interval;
        if let Some(since) = self.file.as_ref().and_then(|f| f.dirty_since) {
            wait = wait.min((since + self.config.flush_interval).saturating_duration_since(now));
        }
        if let Some(at) = self.retry_at {
            wait = wait.min(at.saturating_duration_since(now));
        }
        wait
    }

    pub(super) fn housekeeping(&mut self) {
        self.write_pending_metadata();
        let now = Instant::now();
        if let Some(file) = &mut self.file {
            if file
                .dirty_since
                .is_some_and(|since| now.duration_since(since) >= self.config.flush_interval)
            {
                let records = file.unflushed_records;
                match file.flush() {
                    Ok(()) => {
                        file.unflushed_records = 0;
                        self.shared.flushed.fetch_add(records, Ordering::Relaxed);
                    }
                    Err(e) => self.fail(e),
                }
            }
        } else if self.retry_at.is_some_and(|at| now >= at) {
            self.start_file();
        }
    }

    pub(super) fn write_pending_metadata(&mut self) {
        let pending = std::mem::take(&mut lock(&self.shared.metadata).pending);
        let Some(file) = &mut self.file else {
            // The next file starts with the full, updated set.
            return;
        };
        for (name, map) in &pending {
            if let Err(e) = file.write_metadata(name, map) {
                self.fail(e);
                return;
            }
        }
    }

    pub(super) fn handle(&mut self, record: LogRecord) {
        if self.config.synthetic_start_wall_ns.is_some() {
            self.last_wall_ns = Some(record.t_wall_ns());
        }
        if let LogRecord::Calibration {
            id, toml, noise, ..
        } = &record
        {
            self.noise = *noise;
            let meta = BTreeMap::from([
                ("id".to_string(), id.clone()),
                ("toml".to_string(), toml.clone()),
            ]);
            if let Some(file) = &mut self.file
                && let Err(e) = file.write_metadata(CALIBRATION_METADATA, &meta)
            {
                self.fail(e);
            }
            self.calibration = Some(meta);
        }
        if self.file.as_ref().is_some_and(|f| self.rotation_due(f)) {
            self.rotate();
        }
        let Some(file) = &mut self.file else {
            self.shared
                .dropped_not_logging
                .fetch_add(1, Ordering::Relaxed);
            return;
        };
        match write_record(
            file,
            record,
            &self.config.frame_id,
            self.noise.as_ref(),
            &mut self.scratch,
        ) {
            Ok(()) => {
                file.records += 1;
                file.unflushed_records += 1;
                self.shared.written.fetch_add(1, Ordering::Relaxed);
            }
            Err(e) => {
                self.shared
                    .dropped_not_logging
                    .fetch_add(1, Ordering::Relaxed);
                self.fail(e);
            }
        }
    }

    pub(super) fn rotation_due(&self, file: &OpenFile) -> bool {
        if file.records == 0 {
            return false;
        }
        let by_size = self.config.rotate_size_bytes > 0
            && file.size_estimate() >= self.config.rotate_size_bytes;
        let by_time = self.config.rotate_interval_s > 0.0
            && file.opened.elapsed().as_secs_f64() >= self.config.rotate_interval_s;
        by_size || by_time
    }

    pub(super) fn rotate(&mut self) {
        // Metadata set while this file was open belongs in it too, even when the file fills
        // within one batch of records (the housekeeping pass would come too late).
        self.write_pending_metadata();
        if let Some(file) = self.file.take() {
            let unflushed = file.unflushed_records;
            match file.finish() {
                Ok(()) => {
                    self.shared.flushed.fetch_add(unflushed, Ordering::Relaxed);
                }
                Err(e) => {
                    self.count_lost(unflushed);
                    self.enter_not_logging(&e);
                    return;
                }
            }
        }
        self.start_file();
    }

    /// Records written since the last flush are gone with a failed file.
    pub(super) fn count_lost(&self, records: u64) {
        self.shared.written.fetch_sub(records, Ordering::Relaxed);
        self.shared
            .dropped_not_logging
            .fetch_add(records, Ordering::Relaxed);
    }

    pub(super) fn fail(&mut self, e: RecordingError) {
        if let Some(file) = self.file.take() {
            self.count_lost(file.unflushed_records);
            // Dropping the writer may try to write the summary; it fails quietly on a dead disk.
            drop(file);
        }
        self.enter_not_logging(&e);
    }

    pub(super) fn report_error(&self, e: &RecordingError) {
        let message = error_chain(e);
        tracing::error!(error = %message, "MCAP logging stopped");
        *lock(&self.shared.last_error) = Some(message);
    }

    pub(super) fn enter_not_logging(&mut self, e: &RecordingError) {
        self.report_error(e);
        self.shared.logging.store(false, Ordering::Relaxed);
        *lock(&self.shared.current_file) = None;
        self.retry_at = Some(Instant::now() + self.config.retry_interval);
        tracing::warn!(
            retry_interval = ?self.config.retry_interval,
            "records are dropped until a new recording file can be started"
        );
    }

    /// Starts the next file; on failure, stays (or goes) not logging and schedules a retry.
    pub(super) fn start_file(&mut self) {
        let was_retrying = self.retry_at.is_some();
        match self.open_file() {
            Ok(file) => {
                tracing::info!(path = %file.path.display(), "recording to a new file");
                if was_retrying {
                    tracing::info!("MCAP logging resumed");
                }
                *lock(&self.shared.current_file) = Some(file.path.clone());
                self.shared.files_started.fetch_add(1, Ordering::Relaxed);
                self.shared.logging.store(true, Ordering::Relaxed);
                self.retry_at = None;
                self.file = Some(file);
            }
            Err(e) if was_retrying => {
                // Still failing: say so once per attempt, quietly, with the same detail.
                let message = error_chain(&e);
                tracing::debug!(error = %message, "recording retry failed");
                *lock(&self.shared.last_error) = Some(message);
                self.retry_at = Some(Instant::now() + self.config.retry_interval);
            }
            Err(e) => self.enter_not_logging(&e),
        }
    }

    /// When a file starting now starts: the system clock, or on a synthetic one the last
    /// record's time (the configured start before any).
    fn file_start(&self) -> SystemTime {
        match self.config.synthetic_start_wall_ns {
            None => SystemTime::now(),
            Some(start) => UNIX_EPOCH + Duration::from_nanos(self.last_wall_ns.unwrap_or(start)),
        }
    }

    pub(super) fn open_file(&mut self) -> Result<OpenFile, RecordingError> {
        let started = self.file_start();
        let stamp = utc_stamp(started);
        let mut index = self.next_index;
        let (path, sink) = loop {
            let path = self
                .config
                .dir
                .join(format!("{}-{stamp}-{index:04}.mcap", self.config.prefix));
            match (self.open)(&path) {
                Ok(sink) => break (path, sink),
                // The name is taken (a restart within the same second): take the next index.
                // AlreadyExists also comes from a directory path that is a file, so check.
                Err(e)
                    if e.kind() == io::ErrorKind::AlreadyExists
                        && std::fs::symlink_metadata(&path).is_ok()
                        && index < self.next_index.saturating_add(10_000) =>
                {
                    index += 1;
                }
                Err(source) => return Err(RecordingError::Create { path, source }),
            }
        };
        let file_size = Arc::new(AtomicU64::new(0));
        let counting = CountingSink {
            inner: sink,
            pos: 0,
            size: 0,
            shared: self.shared.clone(),
            file_size: file_size.clone(),
        };
        match self.begin_file(&path, counting, file_size, index, started) {
            Ok(file) => {
                self.next_index = index.saturating_add(1);
                Ok(file)
            }
            Err(e) => {
                // A file that never got its schemas and metadata is only clutter (and on a full
                // disk, retries would leave one every few seconds).
                if let Err(rm) = std::fs::remove_file(&path)
                    && rm.kind() != io::ErrorKind::NotFound
                {
                    tracing::warn!(
                        path = %path.display(),
                        error = %rm,
                        "cannot remove a failed recording file"
                    );
                }
                Err(e)
            }
        }
    }

    pub(super) fn begin_file(
        &mut self,
        path: &Path,
        sink: CountingSink,
        file_size: Arc<AtomicU64>,
        index: u32,
        started: SystemTime,
    ) -> Result<OpenFile, RecordingError> {
        let mcap_err = |source| RecordingError::Write {
            path: path.to_path_buf(),
            source,
        };
        let options = mcap::WriteOptions::new()
            .profile("ros2")
            .library(concat!("imu-rec ", env!("CARGO_PKG_VERSION")))
            .compression(Some(mcap::Compression::Zstd))
            .compression_level(self.config.compression_level)
            // One core is plenty for a few hundred messages a second; leave the rest to the
            // daemon and its subscribers.
            .compression_threads(0)
            .chunk_size(Some(1024 * 1024));
        let mut mcap = options
            .create(BufWriter::with_capacity(64 * 1024, sink))
            .map_err(mcap_err)?;
        let mut channel_ids = [0u16; CHANNELS.len()];
        let no_meta = BTreeMap::new();
        for (id, (topic, def)) in channel_ids.iter_mut().zip(CHANNELS) {
            let schema = mcap
                .add_schema(def.type_name, "ros2msg", def.schema_text().as_bytes())
                .map_err(mcap_err)?;
            *id = mcap
                .add_channel(schema, topic, "cdr", &no_meta)
                .map_err(mcap_err)?;
        }
        let mut file = OpenFile {
            path: path.to_path_buf(),
            mcap,
            channel_ids,
            sequences: [0; CHANNELS.len()],
            file_size,
            opened: Instant::now(),
            records: 0,
            unflushed_records: 0,
            unflushed_bytes: 0,
            dirty_since: None,
        };
        let all = {
            let mut meta = lock(&self.shared.metadata);
            meta.pending.clear();
            meta.all.clone()
        };
        for (name, map) in &all {
            file.write_metadata(name, map)?;
        }
        let recording = BTreeMap::from([
            ("file-index".to_string(), index.to_string()),
            ("prefix".to_string(), self.config.prefix.clone()),
            ("started-utc".to_string(), utc_stamp(started)),
            ("frame-id".to_string(), self.config.frame_id.clone()),
            (
                "library".to_string(),
                concat!("imu-rec ", env!("CARGO_PKG_VERSION")).to_string(),
            ),
        ]);
        file.write_metadata(RECORDING_METADATA, &recording)?;
        if let Some(calibration) = &self.calibration {
            file.write_metadata(CALIBRATION_METADATA, calibration)?;
        }
        // A new file is readable (schemas, channels, metadata) at once.
        file.flush()?;
        Ok(file)
    }
}

pub(super) fn write_record(
    file: &mut OpenFile,
    record: LogRecord,
    frame_id: &str,
    noise: Option<&ImuNoiseVariances>,
    scratch: &mut Vec<u8>,
) -> Result<(), RecordingError> {
    match record {
        LogRecord::RawFrame {
            t_host_wall_ns,
            t_host_monotonic_ns,
            stream_offset,
            accepted,
            reject_reason,
            bytes,
        } => {
            let msg = RawFrameMsg {
                header: header(t_host_wall_ns, frame_id),
                t_host_monotonic_ns,
                stream_offset,
                accepted,
                reject_reason: reject_reason.map(Cow::into_owned).unwrap_or_default(),
                data: bytes.into_vec(),
            };
            file.write_msg(CH_FRAME, t_host_wall_ns, &msg, scratch)
        }
        LogRecord::Sample {
            frame,
            raw,
            corrected,
            compensated,
        } => {
            if let Some(frame) = frame {
                // The accepted frame, at the host times of the read that completed it.
                let frame = LogRecord::RawFrame {
                    t_host_wall_ns: raw.t_host_wall_ns,
                    t_host_monotonic_ns: raw.t_host_monotonic_ns,
                    stream_offset: frame.stream_offset,
                    accepted: true,
                    reject_reason: None,
                    bytes: frame.bytes,
                };
                write_record(file, frame, frame_id, noise, scratch)?;
            }
            write_raw(file, raw, frame_id, scratch)?;
            write_corrected(file, &corrected, frame_id, noise, scratch)?;
            match compensated {
                Some(c) => {
                    let msg = device_compensated_message(corrected.t_wall_ns, &c, frame_id);
                    file.write_msg(CH_DEVICE_COMPENSATED, corrected.t_wall_ns, &msg, scratch)
                }
                None => Ok(()),
            }
        }
        LogRecord::Raw(sample) => write_raw(file, sample, frame_id, scratch),
        LogRecord::Corrected(sample) => write_corrected(file, &sample, frame_id, noise, scratch),
        LogRecord::Temperature { t_wall_ns, temp_c } => {
            let msg = temperature_message(t_wall_ns, temp_c, frame_id);
            file.write_msg(CH_TEMPERATURE, t_wall_ns, &msg, scratch)
        }
        LogRecord::Status { t_wall_ns, status } => {
            let msg = DaemonStatusMsg {
                header: header(t_wall_ns, ""),
                status,
            };
            file.write_msg(CH_STATUS, t_wall_ns, &msg, scratch)
        }
        LogRecord::Health(health) => {
            let msg = CalibrationHealthMsg {
                header: header(health.t_wall_ns, ""),
                health,
            };
            file.write_msg(CH_HEALTH, health.t_wall_ns, &msg, scratch)
        }
        LogRecord::Calibration {
            t_wall_ns,
            id,
            toml,
            ..
        } => {
            let msg = CalibrationMsg {
                header: header(t_wall_ns, ""),
                id,
                toml,
            };
            file.write_msg(CH_CALIBRATION, t_wall_ns, &msg, scratch)
        }
    }
}

/// `/imu/raw`: a raw sample.
fn write_raw(
    file: &mut OpenFile,
    sample: RawSample,
    frame_id: &str,
    scratch: &mut Vec<u8>,
) -> Result<(), RecordingError> {
    let msg = RawSampleMsg {
        header: header(sample.t_host_wall_ns, frame_id),
        sample,
    };
    file.write_msg(CH_RAW, sample.t_host_wall_ns, &msg, scratch)
}

/// `/imu/data` and `/imu/mag`: a corrected sample.
fn write_corrected(
    file: &mut OpenFile,
    sample: &CorrectedSample,
    frame_id: &str,
    noise: Option<&ImuNoiseVariances>,
    scratch: &mut Vec<u8>,
) -> Result<(), RecordingError> {
    let imu = imu_message(sample, frame_id, noise);
    file.write_msg(CH_IMU, sample.t_wall_ns, &imu, scratch)?;
    let mag = magnetic_field_message(sample, frame_id, noise);
    file.write_msg(CH_MAG, sample.t_wall_ns, &mag, scratch)
}
