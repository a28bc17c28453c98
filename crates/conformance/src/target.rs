//! The peer under test, seen through DDS: we play the controller (LowCmd writer with the QoS of
//! Unitree's SDK) and watch its LowState (best-effort reader) and its discovery data.

use crate::ConformError;
use dds_transport::{
    DiscoveredEndpoint, DiscoveryMonitor, DomainConfig, Family, Participant, RawReader, RawWriter, ReaderOptions,
    TopicSpec,
};
use lowlevel_codec::{cdr, crc};
use std::ops::Range;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};
use unitree_idl::{h1_2, hg};

/// At most this many offending raw samples are kept as evidence.
const MAX_KEPT_RAW: usize = 8;

/// One LowState as received.
#[derive(Debug, Clone)]
pub struct StateSample {
    /// Reception time, seconds since the target was connected.
    pub t: f64,
    /// Serialized length (header included).
    pub len: usize,
    /// The decoded message, if the bytes decode as hg LowState.
    pub state: Option<hg::LowState_>,
    /// Why it did not decode.
    pub decode_error: Option<String>,
    /// Whether the stored CRC verifies (false when undecodable).
    pub crc_ok: bool,
    /// The raw bytes, kept for the first few undecodable or bad-CRC samples only.
    pub raw: Option<Vec<u8>>,
}

impl StateSample {
    /// Joint positions of the used slots, if decoded.
    pub fn q(&self) -> Option<[f32; h1_2::NUM_JOINTS]> {
        self.state.as_ref().map(|s| std::array::from_fn(|i| s.motor_state[i].q))
    }
}

/// A connection to the target.
#[derive(Debug)]
pub struct Target {
    writer: RawWriter,
    reader: RawReader,
    discovery: DiscoveryMonitor,
    _participant: Participant,
    config: DomainConfig,
    start: Instant,
    epoch_ns: i64,
    /// Every LowState received so far, in arrival order.
    pub samples: Vec<StateSample>,
    kept_raw: usize,
    /// Commands written so far.
    pub sent: u64,
    /// When each tick of the last [`Target::drive`] was sent, on the clock of [`StateSample::t`] (s): what was in
    /// force at the peer when, as far as the sender decided it.
    pub tick_times: Vec<f64>,
    /// Whether a reader of the target matched our LowCmd writer.
    pub command_reader_matched: bool,
}

fn now_ns() -> i64 {
    SystemTime::now().duration_since(UNIX_EPOCH).map_or(0, |d| i64::try_from(d.as_nanos()).unwrap_or(i64::MAX))
}

impl Target {
    /// Joins the domain and waits up to `timeout` for the target's first LowState (error if none)
    /// and for its LowCmd reader to match our writer (recorded, not required).
    pub fn connect(cfg: DomainConfig, timeout: Duration) -> Result<Target, ConformError> {
        let participant = Participant::new(cfg.clone())?;
        let discovery = participant.discovery()?;
        let writer = participant.writer(&TopicSpec::lowcmd(Family::Hg))?;
        let reader = participant.reader_with(
            &TopicSpec::lowstate(Family::Hg),
            ReaderOptions { queue_capacity: 1 << 16, ..ReaderOptions::default() },
        )?;
        let mut target = Target {
            writer,
            reader,
            discovery,
            _participant: participant,
            config: cfg,
            start: Instant::now(),
            epoch_ns: now_ns(),
            samples: Vec::new(),
            kept_raw: 0,
            sent: 0,
            tick_times: Vec::new(),
            command_reader_matched: false,
        };
        let deadline = Instant::now() + timeout;
        while target.samples.iter().all(|s| s.state.is_none()) {
            if Instant::now() >= deadline {
                return Err(ConformError::NoState { seconds: timeout.as_secs_f64() });
            }
            if let Some(s) = target.reader.take(Duration::from_millis(20)) {
                target.push(s);
            }
        }
        let left = deadline.saturating_duration_since(Instant::now()).max(Duration::from_secs(1));
        target.command_reader_matched = target.writer.wait_for_readers(1, left)?;
        // Discovery data of the target's endpoints arrives with matching; give it a moment.
        let _ = target
            .discovery
            .wait_for(Duration::from_secs(1), |e| !e.local && e.topic_name == unitree_idl::topics::LOWCMD)?;
        target.drain();
        Ok(target)
    }

    /// The domain and interface it joined.
    pub fn config(&self) -> &DomainConfig {
        &self.config
    }

    /// Seconds since connection (the clock of [`StateSample::t`]).
    pub fn elapsed(&self) -> f64 {
        self.start.elapsed().as_secs_f64()
    }

    fn push(&mut self, s: dds_transport::Sample) {
        let t = (s.reception_ns - self.epoch_ns) as f64 * 1e-9;
        let (state, decode_error, crc_ok) = match cdr::decode::<hg::LowState_>(&s.data) {
            Ok(d) => {
                let ok = crc::verify(&d.value);
                (Some(d.value), None, ok)
            }
            Err(e) => (None, Some(e.to_string()), false),
        };
        let raw = (!crc_ok && self.kept_raw < MAX_KEPT_RAW).then(|| {
            self.kept_raw += 1;
            s.data.clone()
        });
        self.samples.push(StateSample { t, len: s.data.len(), state, decode_error, crc_ok, raw });
    }

    /// Moves every queued LowState into [`Target::samples`]; returns how many.
    pub fn drain(&mut self) -> usize {
        let mut n = 0;
        while let Some(s) = self.reader.try_take() {
            self.push(s);
            n += 1;
        }
        n
    }

    /// Forgets all but the newest `keep` samples (long fuzz runs would otherwise hold every
    /// LowState ever received). Ranges returned earlier become invalid.
    pub fn trim(&mut self, keep: usize) {
        let n = self.samples.len().saturating_sub(keep);
        self.samples.drain(..n);
    }

    /// The newest decoded LowState.
    pub fn latest(&self) -> Option<&hg::LowState_> {
        self.samples.iter().rev().find_map(|s| s.state.as_ref())
    }

    /// LowState samples the reader had to drop (queue full).
    pub fn dropped(&self) -> u64 {
        self.reader.dropped()
    }

    /// Publishes one LowCmd sample as given (malformed bytes too; at least 4 bytes).
    pub fn send(&mut self, bytes: &[u8]) -> Result<(), ConformError> {
        self.writer.write(bytes)?;
        self.sent += 1;
        Ok(())
    }

    /// Runs a phase of `duration` seconds: at `rate_hz`, `tick(i)` gives the samples to publish
    /// at tick `i`; LowState is recorded throughout. Returns the range of [`Target::samples`]
    /// received during the phase.
    pub fn drive<F>(&mut self, duration: f64, rate_hz: f64, mut tick: F) -> Result<Range<usize>, ConformError>
    where
        F: FnMut(u64) -> Vec<Vec<u8>>,
    {
        self.drain();
        let first = self.samples.len();
        let begin = Instant::now();
        let period = 1.0 / rate_hz.max(1.0);
        let mut i = 0u64;
        self.tick_times.clear();
        loop {
            let t = begin.elapsed().as_secs_f64();
            if t >= duration {
                break;
            }
            if t >= i as f64 * period {
                for bytes in tick(i) {
                    self.send(&bytes)?;
                }
                self.tick_times.push((now_ns() - self.epoch_ns) as f64 * 1e-9);
                i += 1;
            }
            self.drain();
            let next = (i as f64 * period).min(duration);
            let wait = (next - begin.elapsed().as_secs_f64()).clamp(0.0, 0.001);
            if wait > 0.0 {
                std::thread::sleep(Duration::from_secs_f64(wait));
            }
        }
        self.drain();
        Ok(first..self.samples.len())
    }

    /// Records LowState for `duration` seconds without sending anything.
    pub fn observe(&mut self, duration: f64) -> Result<Range<usize>, ConformError> {
        self.drive(duration, 100.0, |_| Vec::new())
    }

    /// The endpoints other participants announce on `rt/lowcmd` and `rt/lowstate`.
    pub fn remote_endpoints(&self) -> Result<Vec<DiscoveredEndpoint>, ConformError> {
        Ok(self
            .discovery
            .endpoints()?
            .into_iter()
            .filter(|e| {
                !e.local
                    && (e.topic_name == unitree_idl::topics::LOWCMD || e.topic_name == unitree_idl::topics::LOWSTATE)
            })
            .collect())
    }
}
