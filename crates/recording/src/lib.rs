//! The recording format: what `ulab record` writes and `ulab replay`, `ulab log`, `ulab gap` and the
//! benchmarks read and write. One place for its conventions:
//!
//! * MCAP, one channel per DDS topic, channel topic = DDS topic name (`rt/lowstate`);
//! * message encoding `cdr`: each message is the sample exactly as it travelled (encapsulation header included);
//! * channel metadata [`DDS_TYPE_KEY`] holds the DDS type name; the schema (encoding `omgidl`) is the OMG IDL
//!   text of the type generated from `unitree-idl` ([`idl_text`]), or absent for types the codec does not know;
//! * log time = reception time in nanoseconds;
//! * chunks uncompressed by default ([`Compression`]); [`read::messages`] reads zstd, lz4, uncompressed and unchunked
//!   files, whoever wrote them.
//!
//! [`columns`] names the flat CSV columns of a decoded message (`motor_state[3].q`, `imu_state.rpy[2]`).
#![forbid(unsafe_code)]

pub mod columns;
mod idl;
pub mod read;
pub mod recover;

pub use idl::idl_text;
pub use read::{messages, ReadError};
pub use recover::{recover, RecoverError, Recovered};
use std::collections::BTreeMap;
use std::io::{Seek, Write};
use unitree_idl::MessageType;

/// MCAP channel metadata key holding the DDS type name of a channel.
pub const DDS_TYPE_KEY: &str = "dds_type_name";
/// MCAP message encoding of every channel: the CDR sample with its encapsulation header.
pub const MESSAGE_ENCODING: &str = "cdr";
/// MCAP schema encoding of the IDL text stored per known type.
pub const SCHEMA_ENCODING: &str = "omgidl";

/// Chunk compression of a written recording.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Compression {
    /// Uncompressed chunks: the cheapest to write while recording at 500 Hz (the default).
    #[default]
    None,
    /// zstd (level 0, the library's default): what the official writers produce by default, about 5x smaller here.
    Zstd,
    /// lz4: faster than zstd, larger files.
    Lz4,
}

impl Compression {
    /// Every compression, by name.
    pub const ALL: [Compression; 3] = [Compression::None, Compression::Zstd, Compression::Lz4];

    pub fn name(self) -> &'static str {
        match self {
            Compression::None => "none",
            Compression::Zstd => "zstd",
            Compression::Lz4 => "lz4",
        }
    }

    /// Parses `none`, `zstd` or `lz4`.
    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|c| c.name() == s)
    }

    fn to_mcap(self) -> Option<mcap::Compression> {
        match self {
            Compression::None => None,
            Compression::Zstd => Some(mcap::Compression::Zstd),
            Compression::Lz4 => Some(mcap::Compression::Lz4),
        }
    }
}

/// Chunk size of written recordings (bytes before compression).
pub const CHUNK_SIZE: u64 = 256 * 1024;

/// Writer options of every recording the project writes: `library` in the header, chunks of [`CHUNK_SIZE`],
/// the given compression (never the `mcap` crate's default, which is zstd when its `zstd` feature is on).
pub fn write_options(library: &str, compression: Compression) -> mcap::WriteOptions {
    write_options_with_chunk_size(library, compression, CHUNK_SIZE)
}

/// [`write_options`] with another chunk size: a recorder that crashes loses at most the chunk it was filling
/// (see [`recover()`]), so a smaller chunk bounds the loss tighter at the cost of more index records.
pub fn write_options_with_chunk_size(library: &str, compression: Compression, chunk_size: u64) -> mcap::WriteOptions {
    mcap::WriteOptions::new().library(library).chunk_size(Some(chunk_size)).compression(compression.to_mcap())
}

/// The codec's type for a DDS type name, if it knows it.
pub fn kind_of(dds_type_name: &str) -> Option<MessageType> {
    MessageType::ALL.iter().copied().find(|k| k.dds_type_name() == dds_type_name)
}

/// Adds the channel of one DDS topic to `writer`, with its schema when the codec knows the type; returns the
/// channel id.
pub fn add_topic<W: Write + Seek>(
    writer: &mut mcap::Writer<W>,
    topic: &str,
    dds_type_name: &str,
) -> Result<u16, mcap::McapError> {
    let schema_id = match kind_of(dds_type_name) {
        Some(kind) => writer.add_schema(dds_type_name, SCHEMA_ENCODING, idl_text(kind).as_bytes())?,
        None => 0,
    };
    let mut meta = BTreeMap::new();
    meta.insert(DDS_TYPE_KEY.to_owned(), dds_type_name.to_owned());
    writer.add_channel(schema_id, topic, MESSAGE_ENCODING, &meta)
}

/// The DDS type name a recorded channel carries: its [`DDS_TYPE_KEY`] metadata, else its schema name.
pub fn channel_type_name(channel: &mcap::Channel<'_>) -> Option<String> {
    channel.metadata.get(DDS_TYPE_KEY).cloned().or_else(|| channel.schema.as_ref().map(|s| s.name.clone()))
}

/// The `tick` of a LowState sample (hg or go), if it decodes.
pub fn lowstate_tick(kind: MessageType, bytes: &[u8]) -> Option<u32> {
    match kind {
        MessageType::HgLowState => {
            lowlevel_codec::decode::<unitree_idl::hg::LowState_>(bytes).ok().map(|d| d.value.tick)
        }
        MessageType::GoLowState => {
            lowlevel_codec::decode::<unitree_idl::go::LowState_>(bytes).ok().map(|d| d.value.tick)
        }
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn channels_carry_type_schema_and_encoding() {
        let mut buf = std::io::Cursor::new(Vec::new());
        let mut w = write_options("test", Compression::None).create(&mut buf).expect("writer");
        let known = add_topic(&mut w, "rt/lowstate", MessageType::HgLowState.dds_type_name()).expect("known");
        let unknown = add_topic(&mut w, "rt/other", "foo::Bar_").expect("unknown");
        w.write_to_known_channel(
            &mcap::records::MessageHeader { channel_id: known, sequence: 0, log_time: 1, publish_time: 1 },
            &[0, 1, 0, 0],
        )
        .expect("msg");
        w.write_to_known_channel(
            &mcap::records::MessageHeader { channel_id: unknown, sequence: 0, log_time: 2, publish_time: 2 },
            &[0, 1, 0, 0],
        )
        .expect("msg");
        w.finish().expect("finish");
        drop(w);
        let bytes = buf.into_inner();
        let msgs: Vec<_> = messages(&bytes).expect("stream").collect::<Result<_, _>>().expect("read");
        assert_eq!(msgs.len(), 2);
        let ch = &msgs[0].channel;
        assert_eq!((ch.topic.as_str(), ch.message_encoding.as_str()), ("rt/lowstate", "cdr"));
        let schema = ch.schema.as_ref().expect("schema for a known type");
        assert_eq!(schema.encoding, "omgidl");
        assert_eq!(channel_type_name(ch).as_deref(), Some("unitree_hg::msg::dds_::LowState_"));
        assert!(msgs[1].channel.schema.is_none());
        assert_eq!(channel_type_name(&msgs[1].channel).as_deref(), Some("foo::Bar_"));
    }
}
