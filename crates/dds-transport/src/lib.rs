//! Raw-CDR DDS transport over Cyclone DDS (the `cyclors` crate, Cyclone 11.x).
//!
//! Samples are byte strings already serialized by our own codec: CDR with its 4-byte
//! encapsulation header, exactly what goes into an RTPS DATA submessage. Topics use Unitree SDK2's
//! names and type names ([`topics`]), are keyless, and endpoints default to the QoS Unitree's SDK
//! gets from Cyclone (it sets none): writers RELIABLE / KEEP_LAST 1 / VOLATILE, readers
//! BEST_EFFORT / KEEP_LAST 1 / VOLATILE.
//!
//! Interoperability with Unitree's stack on Cyclone DDS 0.10.2:
//! - discovery on loopback works by unicast to participant-index ports ([`DomainConfig`]);
//! - our endpoints advertise no XTypes type information (opaque "blob" sertype), which 0.10.2
//!   peers would fail on.
//!
//! Safety: the default is domain 1 on `lo`; domain 0 or another interface needs
//! [`DomainConfig::allow_robot`].
//!
//! [`probe`] lists the host's interfaces and finds a domain's participants by their SPDP announcements (vendor,
//! protocol and product version), for `ulab doctor`.
//!
//! ```no_run
//! use dds_transport::{DomainConfig, Participant, TopicSpec, topics::Family};
//! use std::time::Duration;
//! let p = Participant::new(DomainConfig::loopback(7))?;
//! let w = p.writer(&TopicSpec::lowcmd(Family::Hg))?;
//! let r = p.reader(&TopicSpec::lowstate(Family::Hg))?;
//! w.write(&[0, 1, 0, 0, /* CDR body */])?;
//! if let Some(s) = r.take(Duration::from_millis(100)) { println!("{} bytes", s.data.len()); }
//! # Ok::<(), dds_transport::Error>(())
//! ```
#![deny(unsafe_code)]
#![warn(missing_docs)]

pub mod config;
mod error;
pub mod probe;
// The crate's only unsafe code: thin Cyclone DDS wrappers, invariants stated in the module.
#[allow(unsafe_code)]
mod ffi;
pub mod topics;

use std::collections::{HashMap, VecDeque};
use std::ffi::CString;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard, OnceLock};
use std::time::{Duration, Instant};

pub use config::{DomainConfig, ParticipantIndex};
pub use error::{Error, Result};
pub use topics::{Family, TopicSpec};

/// One received sample.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Sample {
    /// Serialized bytes as received, encapsulation header included. Not validated in any way.
    pub data: Vec<u8>,
    /// The writer's source timestamp, nanoseconds since the Unix epoch, if it sent one.
    pub source_timestamp_ns: Option<i64>,
    /// When we took it off the reader, nanoseconds since the Unix epoch (system clock).
    pub reception_ns: i64,
    /// Cyclone's handle of the writer that published it (tells writers apart).
    pub publication_handle: u64,
}

/// Reliability kind.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reliability {
    /// Best effort.
    BestEffort,
    /// Reliable.
    Reliable,
}

/// Writer QoS. Default: Unitree's (RELIABLE, KEEP_LAST 1, VOLATILE).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct WriterQos {
    /// Reliability.
    pub reliability: Reliability,
    /// KEEP_LAST depth (at least 1).
    pub history_depth: u32,
}

impl Default for WriterQos {
    fn default() -> Self {
        Self { reliability: Reliability::Reliable, history_depth: 1 }
    }
}

/// Reader options. Default: Unitree's QoS (BEST_EFFORT, KEEP_LAST 1, VOLATILE) and a local queue
/// of 1024 samples (oldest dropped and counted when full).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ReaderOptions {
    /// Reliability requested from writers.
    pub reliability: Reliability,
    /// KEEP_LAST depth of Cyclone's reader history (at least 1). Samples are moved out of it
    /// into our queue as soon as they arrive, so 1 loses nothing unless the listener stalls.
    pub history_depth: u32,
    /// Capacity of the queue that [`RawReader::take`] reads (at least 1).
    pub queue_capacity: usize,
}

impl Default for ReaderOptions {
    fn default() -> Self {
        Self { reliability: Reliability::BestEffort, history_depth: 1, queue_capacity: 1024 }
    }
}

fn qos(reliability: Reliability, depth: u32) -> ffi::EndpointQos {
    ffi::EndpointQos {
        reliable: reliability == Reliability::Reliable,
        depth: i32::try_from(depth.max(1)).unwrap_or(i32::MAX),
    }
}

// One Cyclone domain per id and process: the registry shares it between participants that ask
// for the same configuration and deletes it with the last of them.
struct DomainEntry {
    xml: String,
    entity: ffi::Entity,
    users: usize,
}

fn domains() -> MutexGuard<'static, HashMap<u32, DomainEntry>> {
    static DOMAINS: OnceLock<Mutex<HashMap<u32, DomainEntry>>> = OnceLock::new();
    let m = DOMAINS.get_or_init(|| Mutex::new(HashMap::new()));
    m.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

#[derive(Debug)]
struct ParticipantInner {
    config: DomainConfig,
    entity: ffi::Entity,
}

impl Drop for ParticipantInner {
    fn drop(&mut self) {
        let mut reg = domains();
        ffi::delete(self.entity);
        let remove = match reg.get_mut(&self.config.domain) {
            Some(e) => {
                e.users = e.users.saturating_sub(1);
                e.users == 0
            }
            None => false,
        };
        if remove {
            if let Some(e) = reg.remove(&self.config.domain) {
                ffi::delete(e.entity);
            }
        }
    }
}

/// A DDS participant on one domain and interface. Cheap to clone (shared handle); the
/// participant is deleted when it and all its writers and readers are dropped.
#[derive(Debug, Clone)]
pub struct Participant {
    inner: Arc<ParticipantInner>,
}

impl Participant {
    /// Opens the domain (validating the safety rule) and creates a participant on it.
    ///
    /// Within one process, all participants of a domain must use the same configuration.
    pub fn new(config: DomainConfig) -> Result<Self> {
        config.validate()?;
        let xml = config.to_xml();
        let mut reg = domains();
        match reg.get(&config.domain) {
            Some(e) if e.xml != xml => return Err(Error::DomainConfigConflict { domain: config.domain }),
            Some(_) => {}
            None => {
                let c = CString::new(xml.clone()).map_err(|_| Error::InvalidConfig("NUL in configuration".into()))?;
                let entity = ffi::create_domain(config.domain, &c)?;
                reg.insert(config.domain, DomainEntry { xml, entity, users: 0 });
            }
        }
        let entity = match ffi::create_participant(config.domain) {
            Ok(e) => e,
            Err(err) => {
                if let Some(e) = reg.get(&config.domain) {
                    if e.users == 0 {
                        ffi::delete(e.entity);
                        reg.remove(&config.domain);
                    }
                }
                return Err(err);
            }
        };
        if let Some(e) = reg.get_mut(&config.domain) {
            e.users += 1;
        }
        drop(reg);
        Ok(Self { inner: Arc::new(ParticipantInner { config, entity }) })
    }

    /// The configuration it was created with.
    pub fn config(&self) -> &DomainConfig {
        &self.inner.config
    }

    fn topic(&self, topic: &TopicSpec) -> Result<ffi::Entity> {
        let name = c_name(&topic.name)?;
        let type_name = c_name(&topic.type_name)?;
        ffi::create_blob_topic(self.inner.entity, &name, &type_name)
    }

    /// A writer with Unitree's QoS.
    pub fn writer(&self, topic: &TopicSpec) -> Result<RawWriter> {
        self.writer_with_qos(topic, WriterQos::default())
    }

    /// A writer with the given QoS.
    pub fn writer_with_qos(&self, topic: &TopicSpec, q: WriterQos) -> Result<RawWriter> {
        let t = self.topic(topic)?;
        let handle = ffi::create_writer(self.inner.entity, t, qos(q.reliability, q.history_depth))?;
        Ok(RawWriter { handle, topic: topic.clone(), _participant: self.inner.clone() })
    }

    /// A reader with Unitree's QoS whose samples are queued for [`RawReader::take`].
    pub fn reader(&self, topic: &TopicSpec) -> Result<RawReader> {
        self.reader_with(topic, ReaderOptions::default())
    }

    /// A queued reader with the given options.
    pub fn reader_with(&self, topic: &TopicSpec, opts: ReaderOptions) -> Result<RawReader> {
        let queue = Arc::new(Queue {
            state: Mutex::new(QueueState { samples: VecDeque::new(), dropped: 0 }),
            ready: Condvar::new(),
            capacity: opts.queue_capacity.max(1),
            received: Arc::new(AtomicU64::new(0)),
        });
        let received = queue.received.clone();
        Ok(RawReader { core: self.make_reader(topic, opts, queue.clone(), received)?, queue })
    }

    /// A reader that hands every sample to `callback` on a Cyclone thread, as it arrives (no queue: a
    /// [`CallbackReader`] has nothing to take). The callback must not block for long; a panic in it is caught
    /// and the sample lost.
    pub fn reader_with_callback<F>(&self, topic: &TopicSpec, opts: ReaderOptions, callback: F) -> Result<CallbackReader>
    where
        F: FnMut(Sample) + Send + 'static,
    {
        let received = Arc::new(AtomicU64::new(0));
        let sink = Arc::new(CallbackSink { f: Mutex::new(Box::new(callback)), received: received.clone() });
        Ok(CallbackReader { core: self.make_reader(topic, opts, sink, received)? })
    }

    fn make_reader(
        &self,
        topic: &TopicSpec,
        opts: ReaderOptions,
        sink: Arc<dyn ffi::SampleSink>,
        received: Arc<AtomicU64>,
    ) -> Result<ReaderCore> {
        let t = self.topic(topic)?;
        let handle = ffi::create_reader(self.inner.entity, t, qos(opts.reliability, opts.history_depth), sink)?;
        Ok(ReaderCore { handle, received, topic: topic.clone(), _participant: self.inner.clone() })
    }
}

fn c_name(s: &str) -> Result<CString> {
    if s.is_empty() {
        return Err(Error::InvalidName(s.to_owned()));
    }
    CString::new(s).map_err(|_| Error::InvalidName(s.to_owned()))
}

fn wait_until<F: FnMut() -> Result<bool>>(timeout: Duration, mut f: F) -> Result<bool> {
    let deadline = Instant::now() + timeout;
    loop {
        if f()? {
            return Ok(true);
        }
        if Instant::now() >= deadline {
            return Ok(false);
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// Publishes serialized samples on one topic.
#[derive(Debug)]
pub struct RawWriter {
    handle: ffi::WriterHandle,
    topic: TopicSpec,
    _participant: Arc<ParticipantInner>,
}

impl RawWriter {
    /// Publishes one sample: serialized CDR including the 4-byte encapsulation header. The bytes
    /// are sent as they are (malformed ones too, for robustness tests); only a payload shorter
    /// than the header is refused.
    pub fn write(&self, data: &[u8]) -> Result<()> {
        if data.len() < 4 {
            return Err(Error::PayloadTooShort { len: data.len() });
        }
        self.handle.write(data)
    }

    /// Number of readers currently matched.
    pub fn matched_readers(&self) -> Result<u32> {
        self.handle.matched_readers()
    }

    /// Waits until at least `n` readers are matched; `Ok(false)` on timeout.
    pub fn wait_for_readers(&self, n: u32, timeout: Duration) -> Result<bool> {
        wait_until(timeout, || Ok(self.matched_readers()? >= n))
    }

    /// The topic.
    pub fn topic(&self) -> &TopicSpec {
        &self.topic
    }
}

struct QueueState {
    samples: VecDeque<Sample>,
    dropped: u64,
}

struct Queue {
    state: Mutex<QueueState>,
    ready: Condvar,
    capacity: usize,
    received: Arc<AtomicU64>,
}

impl Queue {
    fn lock(&self) -> MutexGuard<'_, QueueState> {
        self.state.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
    }
}

impl ffi::SampleSink for Queue {
    fn deliver(&self, sample: Sample) {
        self.received.fetch_add(1, Ordering::Relaxed);
        let mut st = self.lock();
        if st.samples.len() >= self.capacity {
            st.samples.pop_front();
            st.dropped += 1;
        }
        st.samples.push_back(sample);
        drop(st);
        self.ready.notify_all();
    }
}

type Callback = Box<dyn FnMut(Sample) + Send>;

struct CallbackSink {
    f: Mutex<Callback>,
    received: Arc<AtomicU64>,
}

impl ffi::SampleSink for CallbackSink {
    fn deliver(&self, sample: Sample) {
        self.received.fetch_add(1, Ordering::Relaxed);
        let mut f = self.f.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        (f)(sample);
    }
}

/// What every reader has: the Cyclone reader, its counter and topic, and the participant kept alive.
#[derive(Debug)]
struct ReaderCore {
    handle: ffi::ReaderHandle,
    received: Arc<AtomicU64>,
    topic: TopicSpec,
    _participant: Arc<ParticipantInner>,
}

/// Receives serialized samples on one topic into a bounded queue, for [`RawReader::take`] and its kin.
#[derive(Debug)]
pub struct RawReader {
    core: ReaderCore,
    queue: Arc<Queue>,
}

/// Receives serialized samples on one topic by handing each to a callback ([`Participant::reader_with_callback`]).
/// A distinct type from [`RawReader`] because it has no queue: there is nothing to take from it.
#[derive(Debug)]
pub struct CallbackReader {
    core: ReaderCore,
}

/// The status methods every reader has, written once for [`RawReader`] and [`CallbackReader`] (both wrap a
/// `ReaderCore` in a field named `core`).
macro_rules! reader_status_methods {
    () => {
        /// Samples received so far (for a [`RawReader`]: queued, taken or dropped; for a [`CallbackReader`]: handed
        /// to the callback).
        pub fn received(&self) -> u64 {
            self.core.received.load(Ordering::Relaxed)
        }

        /// Number of writers currently matched.
        pub fn matched_writers(&self) -> Result<u32> {
            self.core.handle.matched_writers()
        }

        /// Waits until at least `n` writers are matched; `Ok(false)` on timeout.
        pub fn wait_for_writers(&self, n: u32, timeout: Duration) -> Result<bool> {
            wait_until(timeout, || Ok(self.matched_writers()? >= n))
        }

        /// The topic.
        pub fn topic(&self) -> &TopicSpec {
            &self.core.topic
        }
    };
}

impl CallbackReader {
    reader_status_methods!();
}

impl std::fmt::Debug for Queue {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Queue").field("capacity", &self.capacity).finish()
    }
}

impl RawReader {
    /// The oldest queued sample, waiting up to `timeout` for one.
    pub fn take(&self, timeout: Duration) -> Option<Sample> {
        let q = &self.queue;
        let deadline = Instant::now() + timeout;
        let mut st = q.lock();
        loop {
            if let Some(s) = st.samples.pop_front() {
                return Some(s);
            }
            let now = Instant::now();
            if now >= deadline {
                return None;
            }
            st = match q.ready.wait_timeout(st, deadline - now) {
                Ok((g, _)) => g,
                Err(p) => p.into_inner().0,
            };
        }
    }

    /// The oldest queued sample, without waiting.
    pub fn try_take(&self) -> Option<Sample> {
        self.queue.lock().samples.pop_front()
    }

    /// Empties the queue, returning the newest sample and how many older ones were discarded.
    pub fn take_latest(&self) -> Option<(Sample, usize)> {
        let mut st = self.queue.lock();
        let n = st.samples.len();
        let last = st.samples.pop_back()?;
        st.samples.clear();
        Some((last, n.saturating_sub(1)))
    }

    /// Samples dropped because the queue was full.
    pub fn dropped(&self) -> u64 {
        self.queue.lock().dropped
    }

    reader_status_methods!();
}

/// Durability kind.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Durability {
    /// Volatile.
    Volatile,
    /// Transient-local.
    TransientLocal,
    /// Transient.
    Transient,
    /// Persistent.
    Persistent,
}

/// Writer (publication) or reader (subscription).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EndpointKind {
    /// A writer.
    Publication,
    /// A reader.
    Subscription,
}

/// An endpoint as announced in discovery (SEDP), local or remote.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DiscoveredEndpoint {
    /// Writer or reader.
    pub kind: EndpointKind,
    /// Endpoint GUID.
    pub guid: [u8; 16],
    /// GUID of its participant.
    pub participant_guid: [u8; 16],
    /// Whether it belongs to the participant that observes it.
    pub local: bool,
    /// Topic name.
    pub topic_name: String,
    /// DDS type name.
    pub type_name: String,
    /// Reliability, if announced.
    pub reliability: Option<Reliability>,
    /// `Some(depth)` for KEEP_LAST, `Some(-1)` for KEEP_ALL, if announced.
    pub history_depth: Option<i32>,
    /// Durability, if announced.
    pub durability: Option<Durability>,
    /// Whether it carries XTypes type information (Cyclone 0.10.2 peers crash on 11.x's).
    pub has_type_information: bool,
    /// Whether its builtin-topic instance is alive (false: the endpoint was disposed or its
    /// participant unregistered it, or Cyclone has not marked it alive yet).
    pub alive: bool,
}

/// Watches discovery: the endpoints other participants (and this one) announce.
#[derive(Debug)]
pub struct DiscoveryMonitor {
    publications: ffi::Entity,
    subscriptions: ffi::Entity,
    own_guid: [u8; 16],
    participant: Arc<ParticipantInner>,
}

impl Participant {
    /// Starts watching discovery (builtin DCPSPublication / DCPSSubscription topics).
    pub fn discovery(&self) -> Result<DiscoveryMonitor> {
        let own_guid = ffi::guid(self.inner.entity)?;
        let publications = ffi::create_builtin_endpoint_reader(self.inner.entity, true)?;
        let subscriptions = match ffi::create_builtin_endpoint_reader(self.inner.entity, false) {
            Ok(s) => s,
            Err(e) => {
                ffi::delete(publications);
                return Err(e);
            }
        };
        Ok(DiscoveryMonitor { publications, subscriptions, own_guid, participant: self.inner.clone() })
    }
}

impl DiscoveryMonitor {
    /// Every endpoint known to discovery (see [`DiscoveredEndpoint::alive`]).
    pub fn endpoints(&self) -> Result<Vec<DiscoveredEndpoint>> {
        let mut out = Vec::new();
        for (kind, reader) in
            [(EndpointKind::Publication, self.publications), (EndpointKind::Subscription, self.subscriptions)]
        {
            for e in ffi::read_endpoints(reader)? {
                out.push(DiscoveredEndpoint {
                    kind,
                    guid: e.key,
                    participant_guid: e.participant_key,
                    local: e.participant_key == self.own_guid,
                    topic_name: e.topic_name,
                    type_name: e.type_name,
                    reliability: e.reliability.map(|r| if r { Reliability::Reliable } else { Reliability::BestEffort }),
                    history_depth: e.history_keep_last.map(|(keep_last, d)| if keep_last { d } else { -1 }),
                    durability: e.durability.map(|d| match d {
                        0 => Durability::Volatile,
                        1 => Durability::TransientLocal,
                        2 => Durability::Transient,
                        _ => Durability::Persistent,
                    }),
                    has_type_information: e.has_type_info,
                    alive: e.alive,
                });
            }
        }
        Ok(out)
    }

    /// Waits until `pred` holds for some endpoint; returns it, or `None` on timeout.
    pub fn wait_for<F>(&self, timeout: Duration, mut pred: F) -> Result<Option<DiscoveredEndpoint>>
    where
        F: FnMut(&DiscoveredEndpoint) -> bool,
    {
        let deadline = Instant::now() + timeout;
        loop {
            if let Some(e) = self.endpoints()?.into_iter().find(|e| pred(e)) {
                return Ok(Some(e));
            }
            if Instant::now() >= deadline {
                return Ok(None);
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// GUID of the participant it belongs to (its endpoints' `participant_guid`).
    pub fn own_participant_guid(&self) -> [u8; 16] {
        self.own_guid
    }

    /// The participant it belongs to.
    pub fn participant_config(&self) -> &DomainConfig {
        &self.participant.config
    }
}

impl Drop for DiscoveryMonitor {
    fn drop(&mut self) {
        ffi::delete(self.publications);
        ffi::delete(self.subscriptions);
    }
}

// The README's example is compiled (and, where it needs no network, run) as a doctest.
#[doc = include_str!("../README.md")]
#[cfg(doctest)]
pub struct ReadmeDoctests;
