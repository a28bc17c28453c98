//! The only unsafe code of the crate: thin wrappers over Cyclone DDS (through `cyclors`).
//!
//! Invariants kept here, relied on by every function below:
//! - Entities are plain integer handles. Cyclone validates every handle it is given and returns
//!   an error for a stale one, so passing a deleted handle is not memory-unsafe.
//! - Topics are created with cyclors' "blob" sertype (`cdds_create_blob_topic`): a sample is an
//!   opaque byte string (serialized CDR with its 4-byte encapsulation header). That sertype has no
//!   `type_id`/`type_map`/`type_info` operations, so Cyclone advertises no XTypes type
//!   information for our endpoints (Cyclone 0.10.2 peers crash on 11.x type information).
//!   Its `realloc_samples` aborts: we therefore never use `dds_take`/`dds_read`/loans on these
//!   topics, only the serdata-level `dds_writecdr`/`dds_takecdr`.
//! - A `ddsi_serdata` returned by `dds_takecdr` carries one reference that we release with
//!   `ddsi_serdata_unref` exactly once; one created by `ddsi_serdata_from_ser_iov` carries one
//!   reference that `dds_writecdr` consumes on every path once the writer handle is valid.
//! - A reader's listener argument is a `Box<Arc<dyn SampleSink>>` leaked at creation and freed
//!   only after `dds_delete` of the reader has returned; Cyclone guarantees that no listener
//!   callback is running or will run for an entity once its deletion has returned.
//! - No Rust panic crosses the C boundary: the callback body runs under `catch_unwind`.

use std::ffi::{c_void, CStr};
use std::sync::Arc;

use cyclors as cy;

use crate::error::{Error, Result};
use crate::Sample;

/// A Cyclone entity handle.
pub(crate) type Entity = cy::dds_entity_t;

fn check(op: &'static str, rc: i32) -> Result<i32> {
    if rc < 0 {
        Err(dds_error(op, rc))
    } else {
        Ok(rc)
    }
}

pub(crate) fn dds_error(op: &'static str, code: i32) -> Error {
    // SAFETY: dds_strretcode returns a pointer to a static, NUL-terminated string for any code.
    let message = unsafe {
        let p = cy::dds_strretcode(code);
        if p.is_null() {
            String::from("unknown")
        } else {
            CStr::from_ptr(p).to_string_lossy().into_owned()
        }
    };
    Error::Dds { op, code, message }
}

/// Creates a domain with an XML configuration.
pub(crate) fn create_domain(domain: u32, xml: &CStr) -> Result<Entity> {
    // SAFETY: `xml` is a valid NUL-terminated string that Cyclone only reads during the call.
    check("dds_create_domain", unsafe { cy::dds_create_domain(domain, xml.as_ptr()) })
}

/// Creates a participant on an existing domain with default QoS and no listener.
pub(crate) fn create_participant(domain: u32) -> Result<Entity> {
    // SAFETY: null QoS and listener pointers mean defaults.
    check("dds_create_participant", unsafe { cy::dds_create_participant(domain, std::ptr::null(), std::ptr::null()) })
}

/// Deletes an entity and its children. Errors (e.g. already deleted) are ignored.
pub(crate) fn delete(entity: Entity) {
    // SAFETY: any handle value is accepted; invalid ones yield an error code.
    let _ = unsafe { cy::dds_delete(entity) };
}

/// Creates a keyless topic whose samples are opaque serialized bytes.
pub(crate) fn create_blob_topic(participant: Entity, name: &CStr, type_name: &CStr) -> Result<Entity> {
    // SAFETY: both strings are NUL-terminated and outlive the call; cyclocut copies them
    // (ddsi_sertype_init strdup's the type name, dds_create_topic copies the topic name) and
    // does not write through the pointers despite their `char *` type.
    check("cdds_create_blob_topic", unsafe {
        cy::cdds_create_blob_topic(participant, name.as_ptr().cast_mut(), type_name.as_ptr().cast_mut(), true)
    })
}

/// QoS of an endpoint: reliability, KEEP_LAST depth, VOLATILE durability.
#[derive(Debug, Clone, Copy)]
pub(crate) struct EndpointQos {
    pub reliable: bool,
    pub depth: i32,
}

struct Qos(*mut cy::dds_qos_t);

impl Qos {
    fn new(q: EndpointQos) -> Result<Self> {
        // SAFETY: dds_create_qos returns a fresh object or null; setters only write into it.
        unsafe {
            let p = cy::dds_create_qos();
            if p.is_null() {
                return Err(Error::Dds { op: "dds_create_qos", code: -1, message: "out of memory".into() });
            }
            let kind = if q.reliable {
                cy::dds_reliability_kind_DDS_RELIABILITY_RELIABLE
            } else {
                cy::dds_reliability_kind_DDS_RELIABILITY_BEST_EFFORT
            };
            // 100 ms max blocking time: Cyclone's default for writers.
            cy::dds_qset_reliability(p, kind, 100_000_000);
            cy::dds_qset_history(p, cy::dds_history_kind_DDS_HISTORY_KEEP_LAST, q.depth.max(1));
            cy::dds_qset_durability(p, cy::dds_durability_kind_DDS_DURABILITY_VOLATILE);
            Ok(Qos(p))
        }
    }
}

impl Drop for Qos {
    fn drop(&mut self) {
        // SAFETY: created by dds_create_qos, deleted once; Cyclone copies QoS into entities.
        unsafe { cy::dds_delete_qos(self.0) }
    }
}

/// A writer and the sertype pointer used to build serdata for it.
#[derive(Debug)]
pub(crate) struct WriterHandle {
    pub entity: Entity,
    sertype: *const cy::ddsi_sertype,
}

// SAFETY: the sertype pointer is only read by Cyclone (which synchronizes internally) and stays
// valid while the writer entity exists; the handle is an integer.
unsafe impl Send for WriterHandle {}
// SAFETY: as above; `write` takes `&self` and Cyclone's writer is thread-safe.
unsafe impl Sync for WriterHandle {}

pub(crate) fn create_writer(participant: Entity, topic: Entity, q: EndpointQos) -> Result<WriterHandle> {
    let qos = Qos::new(q)?;
    // SAFETY: valid QoS object, null listener.
    let entity =
        check("dds_create_writer", unsafe { cy::dds_create_writer(participant, topic, qos.0, std::ptr::null()) })?;
    let mut sertype: *const cy::ddsi_sertype = std::ptr::null();
    // SAFETY: writes one pointer into `sertype`.
    let rc = unsafe { cy::dds_get_entity_sertype(entity, &mut sertype) };
    if rc < 0 || sertype.is_null() {
        delete(entity);
        return Err(dds_error("dds_get_entity_sertype", rc.min(-1)));
    }
    Ok(WriterHandle { entity, sertype })
}

impl WriterHandle {
    /// Publishes one serialized sample (the bytes are copied).
    pub(crate) fn write(&self, data: &[u8]) -> Result<()> {
        let iov = cy::ddsrt_iovec_t { iov_base: data.as_ptr().cast_mut().cast::<c_void>(), iov_len: data.len() };
        // SAFETY: the blob sertype's from_ser_iov copies `data.len()` bytes out of the one iovec,
        // which points into `data` and is only read during the call.
        let sd =
            unsafe { cy::ddsi_serdata_from_ser_iov(self.sertype, cy::ddsi_serdata_kind_SDK_DATA, 1, &iov, data.len()) };
        if sd.is_null() {
            return Err(Error::Dds { op: "ddsi_serdata_from_ser_iov", code: -1, message: "null serdata".into() });
        }
        // SAFETY: `sd` holds one reference which dds_writecdr consumes on every path.
        check("dds_writecdr", unsafe { cy::dds_writecdr(self.entity, sd) }).map(|_| ())
    }

    pub(crate) fn matched_readers(&self) -> Result<u32> {
        let mut st: cy::dds_publication_matched_status_t = cy::dds_publication_matched_status_t {
            total_count: 0,
            total_count_change: 0,
            current_count: 0,
            current_count_change: 0,
            last_subscription_handle: 0,
        };
        // SAFETY: writes one status struct.
        check("dds_get_publication_matched_status", unsafe {
            cy::dds_get_publication_matched_status(self.entity, &mut st)
        })?;
        Ok(st.current_count)
    }
}

impl Drop for WriterHandle {
    fn drop(&mut self) {
        delete(self.entity);
    }
}

/// Where a reader's samples go; called on a Cyclone thread.
pub(crate) trait SampleSink: Send + Sync {
    fn deliver(&self, sample: Sample);
}

type SinkBox = Arc<dyn SampleSink>;

/// A reader with its listener argument.
pub(crate) struct ReaderHandle {
    pub entity: Entity,
    arg: *mut SinkBox,
}

impl std::fmt::Debug for ReaderHandle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ReaderHandle").field("entity", &self.entity).finish()
    }
}

// SAFETY: `arg` is only dereferenced by the listener callback (shared, Sync contents) and freed
// in Drop after the reader is deleted.
unsafe impl Send for ReaderHandle {}
// SAFETY: as above.
unsafe impl Sync for ReaderHandle {}

pub(crate) fn create_reader(participant: Entity, topic: Entity, q: EndpointQos, sink: SinkBox) -> Result<ReaderHandle> {
    let qos = Qos::new(q)?;
    let arg: *mut SinkBox = Box::into_raw(Box::new(sink));
    // SAFETY: the listener object is copied into the reader by dds_create_reader and deleted
    // right after; `arg` stays valid until ReaderHandle::drop (see module invariants).
    let rc = unsafe {
        let listener = cy::dds_create_listener(arg.cast::<c_void>());
        if listener.is_null() {
            drop(Box::from_raw(arg));
            return Err(Error::Dds { op: "dds_create_listener", code: -1, message: "out of memory".into() });
        }
        cy::dds_lset_data_available(listener, Some(on_data_available));
        let rc = cy::dds_create_reader(participant, topic, qos.0, listener);
        cy::dds_delete_listener(listener);
        rc
    };
    if rc < 0 {
        // SAFETY: no reader exists, so no callback can hold `arg`.
        drop(unsafe { Box::from_raw(arg) });
        return Err(dds_error("dds_create_reader", rc));
    }
    Ok(ReaderHandle { entity: rc, arg })
}

impl ReaderHandle {
    pub(crate) fn matched_writers(&self) -> Result<u32> {
        let mut st = cy::dds_subscription_matched_status_t {
            total_count: 0,
            total_count_change: 0,
            current_count: 0,
            current_count_change: 0,
            last_publication_handle: 0,
        };
        // SAFETY: writes one status struct.
        check("dds_get_subscription_matched_status", unsafe {
            cy::dds_get_subscription_matched_status(self.entity, &mut st)
        })?;
        Ok(st.current_count)
    }
}

impl Drop for ReaderHandle {
    fn drop(&mut self) {
        delete(self.entity);
        // SAFETY: the reader is deleted (or was deleted with its participant, which the owner
        // keeps alive until now), so no callback runs or will run with `arg`.
        drop(unsafe { Box::from_raw(self.arg) });
    }
}

fn now_ns() -> i64 {
    match std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH) {
        Ok(d) => i64::try_from(d.as_nanos()).unwrap_or(i64::MAX),
        Err(_) => 0,
    }
}

unsafe extern "C" fn on_data_available(reader: Entity, arg: *mut c_void) {
    if arg.is_null() {
        return;
    }
    // SAFETY: `arg` is the `*mut SinkBox` installed by create_reader, alive while callbacks run.
    let sink: &SinkBox = unsafe { &*arg.cast::<SinkBox>() };
    let _ = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| loop {
        let mut sd: *mut cy::ddsi_serdata = std::ptr::null_mut();
        // SAFETY: zeroed sample info is a valid value of a plain C struct.
        let mut info: cy::dds_sample_info_t = unsafe { std::mem::zeroed() };
        // SAFETY: room for exactly one serdata pointer and one sample info.
        let n = unsafe { cy::dds_takecdr(reader, &mut sd, 1, &mut info, cy::DDS_ANY_STATE) };
        if n <= 0 || sd.is_null() {
            break;
        }
        let reception_ns = now_ns();
        // SAFETY: `sd` is a live serdata with one reference owned by us.
        let data = if info.valid_data { unsafe { serdata_bytes(sd) } } else { None };
        // SAFETY: releases the reference dds_takecdr gave us, exactly once.
        unsafe { cy::ddsi_serdata_unref(sd) };
        if let Some(data) = data {
            let source_timestamp_ns =
                if info.source_timestamp == i64::MIN { None } else { Some(info.source_timestamp) };
            sink.deliver(Sample {
                data,
                source_timestamp_ns,
                reception_ns,
                publication_handle: info.publication_handle,
            });
        }
    }));
}

/// Copies the serialized bytes (encapsulation header included) out of a serdata.
///
/// # Safety
/// `sd` must point to a live serdata.
unsafe fn serdata_bytes(sd: *mut cy::ddsi_serdata) -> Option<Vec<u8>> {
    // SAFETY: per the function contract.
    unsafe {
        let size = cy::ddsi_serdata_size(sd) as usize;
        if size == 0 {
            return Some(Vec::new());
        }
        let mut iov = cy::ddsrt_iovec_t { iov_base: std::ptr::null_mut(), iov_len: 0 };
        let r = cy::ddsi_serdata_to_ser_ref(sd, 0, size, &mut iov);
        if r.is_null() {
            return None;
        }
        let out = if iov.iov_base.is_null() || iov.iov_len > size {
            None
        } else {
            Some(std::slice::from_raw_parts(iov.iov_base.cast::<u8>(), iov.iov_len).to_vec())
        };
        cy::ddsi_serdata_to_ser_unref(r, &iov);
        out
    }
}

/// One endpoint read from a builtin topic, copied out of Cyclone's loan.
#[derive(Debug, Clone)]
pub(crate) struct RawEndpoint {
    pub key: [u8; 16],
    pub participant_key: [u8; 16],
    pub topic_name: String,
    pub type_name: String,
    pub reliability: Option<bool>,
    pub history_keep_last: Option<(bool, i32)>,
    pub durability: Option<u32>,
    pub has_type_info: bool,
    pub alive: bool,
}

/// GUID of an entity.
pub(crate) fn guid(entity: Entity) -> Result<[u8; 16]> {
    let mut g = cy::dds_guid_t { v: [0; 16] };
    // SAFETY: writes one GUID.
    check("dds_get_guid", unsafe { cy::dds_get_guid(entity, &mut g) })?;
    Ok(g.v)
}

/// A reader of the DCPSPublication (`publications = true`) or DCPSSubscription builtin topic,
/// with Cyclone's builtin QoS. These readers use Cyclone's own builtin sertype, so reading with
/// loans (`dds_read_mask` + `dds_return_loan`) is valid here, unlike on our blob topics.
pub(crate) fn create_builtin_endpoint_reader(participant: Entity, publications: bool) -> Result<Entity> {
    let topic =
        if publications { cy::DDS_BUILTIN_TOPIC_DCPSPUBLICATION } else { cy::DDS_BUILTIN_TOPIC_DCPSSUBSCRIPTION };
    // SAFETY: pseudo-handle topic, default QoS, no listener.
    check("dds_create_reader(builtin)", unsafe {
        cy::dds_create_reader(participant, topic, std::ptr::null(), std::ptr::null())
    })
}

fn c_string(p: *const std::os::raw::c_char) -> String {
    if p.is_null() {
        String::new()
    } else {
        // SAFETY: non-null pointers in builtin samples are NUL-terminated strings owned by the
        // loaned sample, alive until the loan is returned (after this copy).
        unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned()
    }
}

/// Reads (without taking) every endpoint known to a builtin endpoint reader, with its instance
/// state (alive or not: disposed/unregistered endpoints stay until taken).
pub(crate) fn read_endpoints(reader: Entity) -> Result<Vec<RawEndpoint>> {
    const N: usize = 256;
    let mut out = Vec::new();
    let mut buf: [*mut c_void; N] = [std::ptr::null_mut(); N];
    // SAFETY: zeroed sample infos are valid plain C structs.
    let mut infos: [cy::dds_sample_info_t; N] = unsafe { std::mem::zeroed() };
    let mask = cy::DDS_ANY_STATE;
    // SAFETY: buf[0] == null asks Cyclone to loan up to N samples into `buf`; `infos` has N
    // entries. The loan is returned below before `buf` goes out of scope.
    let n = check("dds_read_mask", unsafe {
        cy::dds_read_mask(reader, buf.as_mut_ptr(), infos.as_mut_ptr(), N, N as u32, mask)
    })?;
    let n = usize::try_from(n).unwrap_or(0).min(N);
    for i in 0..n {
        if !infos[i].valid_data || buf[i].is_null() {
            continue;
        }
        let ep = buf[i].cast::<cy::dds_builtintopic_endpoint_t>();
        // SAFETY: a valid loaned sample of the endpoint builtin topic; we only read from it
        // (the `*mut` of get_endpoint_type_info is historical: it does not write).
        unsafe {
            let e = &*ep;
            let mut rel_kind: cy::dds_reliability_kind_t = 0;
            let mut max_block: cy::dds_duration_t = 0;
            let reliability = if !e.qos.is_null() && cy::dds_qget_reliability(e.qos, &mut rel_kind, &mut max_block) {
                Some(rel_kind == cy::dds_reliability_kind_DDS_RELIABILITY_RELIABLE)
            } else {
                None
            };
            let mut hist_kind: cy::dds_history_kind_t = 0;
            let mut depth: i32 = 0;
            let history_keep_last = if !e.qos.is_null() && cy::dds_qget_history(e.qos, &mut hist_kind, &mut depth) {
                Some((hist_kind == cy::dds_history_kind_DDS_HISTORY_KEEP_LAST, depth))
            } else {
                None
            };
            let mut dur: cy::dds_durability_kind_t = 0;
            let durability =
                if !e.qos.is_null() && cy::dds_qget_durability(e.qos, &mut dur) { Some(dur as u32) } else { None };
            let mut ti: *const cy::dds_typeinfo_t = std::ptr::null();
            let has_type_info = cy::dds_builtintopic_get_endpoint_type_info(ep, &mut ti) == 0 && !ti.is_null();
            out.push(RawEndpoint {
                key: e.key.v,
                participant_key: e.participant_key.v,
                topic_name: c_string(e.topic_name),
                type_name: c_string(e.type_name),
                reliability,
                history_keep_last,
                durability,
                has_type_info,
                alive: infos[i].instance_state == cy::dds_instance_state_DDS_IST_ALIVE,
            });
        }
    }
    if n > 0 {
        // SAFETY: returns exactly the loan obtained above.
        unsafe { cy::dds_return_loan(reader, buf.as_mut_ptr(), n as i32) };
    }
    Ok(out)
}
