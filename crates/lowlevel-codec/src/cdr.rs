//! CDR encoding of `@final` IDL structs: XCDR1 (`CDR_LE`/`CDR_BE`) and XCDR2 (`CDR2_LE`/`CDR2_BE`,
//! "plain"), preceded by the 4-byte encapsulation header of DDS-RTPS / DDS-XTypes.
//!
//! Layout rules (DDS-XTypes 1.3, 7.4.3):
//! * every primitive is aligned to its size, relative to the first byte after the header, capped
//!   at 8 in XCDR1 and 4 in XCDR2; padding is written as zeros and ignored when read;
//! * structs add no padding of their own (no tail padding), unlike the C struct image;
//! * XCDR2 prefixes every array or sequence of non-primitive elements with a 4-byte DHEADER, the
//!   byte length of what follows; `@final` structs themselves get none;
//! * sequences carry a 4-byte element count; their elements are aligned only when there is one;
//! * strings are a 4-byte length that counts the terminating NUL, the UTF-8 bytes and the NUL
//!   (never a DHEADER); booleans are one byte, 0 or 1.
//!
//! The header's two option bytes may declare 0..3 bytes of padding at the end of the payload
//! (XTypes 7.6.3.1.2); we honour them when reading and write none.

use unitree_idl::{align_up, IdlStruct, PrimKind, Primitive, Visitor, VisitorMut};

/// Length of the encapsulation header.
pub const HEADER_LEN: usize = 4;

/// CDR representation version.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Representation {
    /// XCDR version 1 (what Unitree's SDKs and Cyclone DDS 0.10 put on the wire).
    Xcdr1,
    /// XCDR version 2, plain (no member headers: `@final` types).
    Xcdr2,
}

impl Representation {
    /// Lower-case name used in JSON documents and on the command line.
    pub const fn name(self) -> &'static str {
        match self {
            Representation::Xcdr1 => "xcdr1",
            Representation::Xcdr2 => "xcdr2",
        }
    }

    /// Parses [`Representation::name`].
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "xcdr1" => Some(Representation::Xcdr1),
            "xcdr2" => Some(Representation::Xcdr2),
            _ => None,
        }
    }

    /// Largest alignment a primitive gets: 8 in XCDR1, 4 in XCDR2.
    pub const fn max_align(self) -> usize {
        match self {
            Representation::Xcdr1 => 8,
            Representation::Xcdr2 => 4,
        }
    }

    /// Payload offset where a primitive of `size` bytes goes when the cursor is at `pos`: the
    /// one statement of CDR's alignment rule, used by the writer, the reader and [`view`](mod@crate::view).
    #[inline(always)]
    pub const fn align(self, pos: usize, size: usize) -> usize {
        let max = self.max_align();
        align_up(pos, if size < max { size } else { max })
    }

    /// Whether arrays and sequences of structs are framed by a DHEADER (XCDR2 only).
    pub const fn has_dheader(self) -> bool {
        matches!(self, Representation::Xcdr2)
    }

    /// Index of this representation in per-representation tables.
    pub(crate) const fn index(self) -> usize {
        match self {
            Representation::Xcdr1 => 0,
            Representation::Xcdr2 => 1,
        }
    }
}

/// Byte order of the payload.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Endianness {
    /// Little-endian (what Unitree's SDKs send).
    Little,
    /// Big-endian.
    Big,
}

impl Endianness {
    /// Lower-case name used in JSON documents.
    pub const fn name(self) -> &'static str {
        match self {
            Endianness::Little => "little",
            Endianness::Big => "big",
        }
    }

    /// Parses [`Endianness::name`].
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "little" => Some(Endianness::Little),
            "big" => Some(Endianness::Big),
            _ => None,
        }
    }
}

/// Representation and byte order together: what the encapsulation header says.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Encoding {
    /// XCDR1 or XCDR2.
    pub representation: Representation,
    /// Byte order of the payload.
    pub endianness: Endianness,
}

impl Encoding {
    /// What Unitree's SDKs send: XCDR1, little-endian (header `00 01 00 00`).
    pub const UNITREE: Encoding = Encoding { representation: Representation::Xcdr1, endianness: Endianness::Little };

    /// Encapsulation identifier (first two header bytes, big-endian).
    pub const fn identifier(self) -> u16 {
        match (self.representation, self.endianness) {
            (Representation::Xcdr1, Endianness::Big) => 0x0000,
            (Representation::Xcdr1, Endianness::Little) => 0x0001,
            (Representation::Xcdr2, Endianness::Big) => 0x0006,
            (Representation::Xcdr2, Endianness::Little) => 0x0007,
        }
    }

    /// Encoding named by an encapsulation identifier, or why it cannot be decoded here.
    pub fn from_identifier(id: u16) -> Result<Encoding, DecodeError> {
        use Endianness::*;
        use Representation::*;
        let (representation, endianness) = match id {
            0x0000 => (Xcdr1, Big),
            0x0001 => (Xcdr1, Little),
            0x0006 => (Xcdr2, Big),
            0x0007 => (Xcdr2, Little),
            0x0002 | 0x0003 => {
                return Err(DecodeError::UnsupportedRepresentation {
                    id,
                    name: "PL_CDR (XCDR1 parameter list, mutable types)",
                })
            }
            0x0008 | 0x0009 => {
                return Err(DecodeError::UnsupportedRepresentation {
                    id,
                    name: "D_CDR2 (XCDR2 delimited, appendable types)",
                })
            }
            0x000a | 0x000b => {
                return Err(DecodeError::UnsupportedRepresentation {
                    id,
                    name: "PL_CDR2 (XCDR2 parameter list, mutable types)",
                })
            }
            0x0004 | 0x0005 => return Err(DecodeError::UnsupportedRepresentation { id, name: "XML" }),
            _ => return Err(DecodeError::UnknownRepresentation { id }),
        };
        Ok(Encoding { representation, endianness })
    }

    /// The 4-byte encapsulation header with zero options.
    pub const fn header(self) -> [u8; HEADER_LEN] {
        let id = self.identifier().to_be_bytes();
        [id[0], id[1], 0, 0]
    }
}

/// Why a byte string is not a valid CDR encoding of the requested type.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum DecodeError {
    /// The input cannot even hold the encapsulation header.
    #[error("input is {len} bytes, shorter than the 4-byte encapsulation header")]
    MissingHeader {
        /// Length of the input (bytes).
        len: usize,
    },
    /// The header's encapsulation identifier is not one the DDS specification defines.
    #[error("unknown encapsulation identifier {id:#06x}")]
    UnknownRepresentation {
        /// The identifier (first two header bytes, big-endian).
        id: u16,
    },
    /// A defined encapsulation that SDK2's `@final` types never use (parameter lists, delimited
    /// CDR2, XML).
    #[error("encapsulation {id:#06x} is {name}; SDK2 types are @final and use plain CDR or CDR2")]
    UnsupportedRepresentation {
        /// The identifier (first two header bytes, big-endian).
        id: u16,
        /// What that identifier stands for.
        name: &'static str,
    },
    /// The input ends inside a member.
    #[error("truncated in member `{member}` at payload offset {offset}: needs {needed} bytes, {available} left")]
    Truncated {
        /// IDL name of the member being read.
        member: &'static str,
        /// Payload offset (after the header) where the read starts, padding included.
        offset: usize,
        /// Bytes the read needs.
        needed: usize,
        /// Bytes left from `offset` to the end of the payload.
        available: usize,
    },
    /// A sequence length that the remaining bytes cannot hold (checked before allocating).
    #[error(
        "sequence `{member}` at payload offset {offset} claims {count} elements, but only {available} bytes remain"
    )]
    BadSequenceLength {
        /// IDL name of the sequence member.
        member: &'static str,
        /// Payload offset of the length word.
        offset: usize,
        /// Element count the length word claims.
        count: u32,
        /// Bytes left after the length word.
        available: usize,
    },
    /// An XCDR2 DHEADER whose byte count differs from the size of the elements it frames.
    #[error(
        "DHEADER of `{member}` at payload offset {offset} declares {declared} bytes, but its elements take {actual}"
    )]
    BadDheader {
        /// IDL name of the framed array or sequence.
        member: &'static str,
        /// Payload offset of the DHEADER.
        offset: usize,
        /// Byte count the DHEADER declares.
        declared: u32,
        /// Bytes the elements actually take.
        actual: usize,
    },
    /// A `boolean` byte other than 0 or 1.
    #[error("boolean `{member}` at payload offset {offset} is {value}, not 0 or 1")]
    InvalidBool {
        /// IDL name of the member.
        member: &'static str,
        /// Payload offset of the byte.
        offset: usize,
        /// The byte found.
        value: u8,
    },
    /// A malformed string.
    #[error("string `{member}` at payload offset {offset}: {reason}")]
    BadString {
        /// IDL name of the string member.
        member: &'static str,
        /// Payload offset of its length word.
        offset: usize,
        /// What is wrong with it.
        reason: StringFault,
    },
    /// The header's option bytes declare more padding than there is payload.
    #[error("header declares {padding} padding bytes, more than the {payload} payload bytes")]
    BadPadding {
        /// Padding bytes declared (low two bits of the options).
        padding: usize,
        /// Payload bytes present after the header.
        payload: usize,
    },
    /// Bytes left over once the whole message is read.
    #[error("{count} trailing byte(s) after the message (payload offset {offset})")]
    TrailingBytes {
        /// Payload offset where the message ended.
        offset: usize,
        /// Number of extra bytes.
        count: usize,
    },
}

/// What is wrong with a CDR string.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum StringFault {
    /// The length word is 0: a CDR string always counts its terminating NUL.
    #[error("length 0 (a CDR string counts its terminating NUL)")]
    ZeroLength,
    /// The last byte the length covers is not NUL.
    #[error("not terminated by NUL")]
    Unterminated,
    /// The characters are not UTF-8 (at this byte of the string).
    #[error("not UTF-8 (byte {at})")]
    NotUtf8 {
        /// Offset within the string of the first byte that is not valid UTF-8.
        at: usize,
    },
}

/// A decoded message and how it was encoded.
#[derive(Debug, Clone, PartialEq)]
pub struct Decoded<T> {
    /// The decoded message.
    pub value: T,
    /// Representation and byte order from the header.
    pub encoding: Encoding,
    /// Option bytes of the header (big-endian), as received.
    pub options: u16,
}

/// Encodes `value` with its encapsulation header.
pub fn encode<T: IdlStruct>(value: &T, encoding: Encoding) -> Vec<u8> {
    let mut out = Vec::with_capacity(HEADER_LEN + 64 + T::CDR_MIN + T::CDR_MIN / 4);
    encode_into(value, encoding, &mut out);
    out
}

/// Appends the encapsulation header and the encoding of `value` to `out`.
pub fn encode_into<T: IdlStruct>(value: &T, encoding: Encoding, out: &mut Vec<u8>) {
    out.extend_from_slice(&encoding.header());
    let origin = out.len();
    match (encoding.endianness, encoding.representation) {
        (Endianness::Little, Representation::Xcdr1) => value.walk(&mut Writer::<false, false> { out, origin }),
        (Endianness::Little, Representation::Xcdr2) => value.walk(&mut Writer::<false, true> { out, origin }),
        (Endianness::Big, Representation::Xcdr1) => value.walk(&mut Writer::<true, false> { out, origin }),
        (Endianness::Big, Representation::Xcdr2) => value.walk(&mut Writer::<true, true> { out, origin }),
    }
}

/// Reads the encapsulation header: the encoding, the option bytes and the payload without the
/// padding the options declare. Shared by [`decode`] and [`crate::view::view`].
pub(crate) fn split_sample(bytes: &[u8]) -> Result<(Encoding, u16, &[u8]), DecodeError> {
    let Some((header, payload)) = bytes.split_first_chunk::<HEADER_LEN>() else {
        return Err(DecodeError::MissingHeader { len: bytes.len() });
    };
    let encoding = Encoding::from_identifier(u16::from_be_bytes([header[0], header[1]]))?;
    let options = u16::from_be_bytes([header[2], header[3]]);
    let padding = usize::from(options & 0x3);
    let Some(body_len) = payload.len().checked_sub(padding) else {
        return Err(DecodeError::BadPadding { padding, payload: payload.len() });
    };
    Ok((encoding, options, &payload[..body_len]))
}

/// The error for bytes left over once the message is read.
pub(crate) fn trailing(consumed: usize, body_len: usize) -> DecodeError {
    DecodeError::TrailingBytes { offset: consumed, count: body_len - consumed }
}

/// Decodes a complete sample (header and payload). Every byte must be accounted for.
pub fn decode<T: IdlStruct>(bytes: &[u8]) -> Result<Decoded<T>, DecodeError> {
    let (encoding, options, body) = split_sample(bytes)?;
    let mut value = T::zeroed();
    let consumed = match (encoding.endianness, encoding.representation) {
        (Endianness::Little, Representation::Xcdr1) => read_into::<T, false, false>(body, &mut value)?,
        (Endianness::Little, Representation::Xcdr2) => read_into::<T, false, true>(body, &mut value)?,
        (Endianness::Big, Representation::Xcdr1) => read_into::<T, true, false>(body, &mut value)?,
        (Endianness::Big, Representation::Xcdr2) => read_into::<T, true, true>(body, &mut value)?,
    };
    if consumed != body.len() {
        return Err(trailing(consumed, body.len()));
    }
    Ok(Decoded { value, encoding, options })
}

/// Size of the CDR payload (without header) of `value`.
pub fn encoded_len<T: IdlStruct>(value: &T, representation: Representation) -> usize {
    encode(value, Encoding { representation, endianness: Endianness::Little }).len() - HEADER_LEN
}

/// Encoding cursor; byte order and representation are type parameters (see `Reader`).
struct Writer<'o, const BIG: bool, const V2: bool> {
    out: &'o mut Vec<u8>,
    origin: usize,
}

/// The representation a `V2` type parameter stands for.
const fn representation(v2: bool) -> Representation {
    if v2 {
        Representation::Xcdr2
    } else {
        Representation::Xcdr1
    }
}

impl<const BIG: bool, const V2: bool> Writer<'_, BIG, V2> {
    const REPRESENTATION: Representation = representation(V2);

    #[inline(always)]
    fn align(&mut self, size: usize) {
        let pos = self.out.len() - self.origin;
        let pad = Self::REPRESENTATION.align(pos, size) - pos;
        if pad != 0 {
            self.out.extend_from_slice(&[0u8; 8][..pad]);
        }
    }

    #[inline(always)]
    fn put<P: Primitive>(&mut self, value: P) {
        let bits = value.to_bits();
        match P::SIZE {
            1 => self.out.push(bits as u8),
            2 => {
                self.out.extend_from_slice(&if BIG { (bits as u16).to_be_bytes() } else { (bits as u16).to_le_bytes() })
            }
            4 => {
                self.out.extend_from_slice(&if BIG { (bits as u32).to_be_bytes() } else { (bits as u32).to_le_bytes() })
            }
            _ => self.out.extend_from_slice(&if BIG { bits.to_be_bytes() } else { bits.to_le_bytes() }),
        }
    }

    #[inline(always)]
    fn put_u32(&mut self, value: u32) {
        self.align(4);
        self.put(value);
    }

    /// Lengths beyond u32 cannot be expressed in CDR; nothing in the SDK comes close.
    fn put_len(&mut self, len: usize) {
        self.put_u32(u32::try_from(len).unwrap_or(u32::MAX));
    }

    /// Writes a DHEADER placeholder and returns where to patch it.
    fn begin_dheader(&mut self) -> usize {
        self.put_u32(0);
        self.out.len()
    }

    fn end_dheader(&mut self, content_start: usize) {
        let len = (self.out.len() - content_start) as u32;
        let bytes = if BIG { len.to_be_bytes() } else { len.to_le_bytes() };
        self.out[content_start - 4..content_start].copy_from_slice(&bytes);
    }
}

impl<const BIG: bool, const V2: bool> Visitor for Writer<'_, BIG, V2> {
    #[inline(always)]
    fn primitive<P: Primitive>(&mut self, _name: &'static str, value: &P) {
        self.align(P::SIZE);
        self.put(*value);
    }

    #[inline(always)]
    fn primitive_array<P: Primitive>(&mut self, _name: &'static str, items: &[P]) {
        self.align(P::SIZE);
        self.out.reserve(items.len() * P::SIZE);
        for item in items {
            self.put(*item);
        }
    }

    #[inline(always)]
    fn structure<S: IdlStruct>(&mut self, _name: &'static str, value: &S) {
        value.walk(self);
    }

    fn struct_array<S: IdlStruct>(&mut self, _name: &'static str, items: &[S]) {
        if Self::REPRESENTATION.has_dheader() {
            let start = self.begin_dheader();
            items.iter().for_each(|item| item.walk(self));
            self.end_dheader(start);
        } else {
            items.iter().for_each(|item| item.walk(self));
        }
    }

    fn struct_sequence<S: IdlStruct>(&mut self, _name: &'static str, items: &[S]) {
        if Self::REPRESENTATION.has_dheader() {
            let start = self.begin_dheader();
            self.put_len(items.len());
            items.iter().for_each(|item| item.walk(self));
            self.end_dheader(start);
        } else {
            self.put_len(items.len());
            items.iter().for_each(|item| item.walk(self));
        }
    }

    fn primitive_sequence<P: Primitive>(&mut self, name: &'static str, items: &[P]) {
        // No DHEADER in XCDR2: the elements are primitives.
        self.put_len(items.len());
        if !items.is_empty() {
            self.primitive_array(name, items);
        }
    }

    fn string(&mut self, _name: &'static str, value: &str) {
        self.put_len(value.len() + 1);
        self.out.extend_from_slice(value.as_bytes());
        self.out.push(0);
    }
}

/// Decodes `body` into `value`; returns the bytes consumed.
fn read_into<T: IdlStruct, const BIG: bool, const V2: bool>(body: &[u8], value: &mut T) -> Result<usize, DecodeError> {
    let mut r = Reader::<BIG, V2> { buf: body, pos: 0 };
    value.walk_mut(&mut r)?;
    Ok(r.pos)
}

/// Decoding cursor; byte order and representation are type parameters so that alignment
/// masks and byte swaps fold into constants on the hot path.
struct Reader<'b, const BIG: bool, const V2: bool> {
    buf: &'b [u8],
    pos: usize,
}

/// The error for a member of `len` bytes at payload offset `start` that does not fit in
/// `buf_len` bytes. Shared with [`crate::view`], which must report exactly what the reader does.
#[cold]
#[inline(never)]
pub(crate) fn truncated(member: &'static str, start: usize, len: usize, buf_len: usize) -> DecodeError {
    DecodeError::Truncated { member, offset: start.min(buf_len), needed: len, available: buf_len.saturating_sub(start) }
}

/// A primitive from its `P::SIZE` bytes in the given byte order (the one place bytes become
/// values; [`crate::view`] reads through it too).
#[inline(always)]
pub(crate) fn get<P: Primitive, const BIG: bool>(bytes: &[u8]) -> P {
    let bits = match P::SIZE {
        1 => u64::from(bytes[0]),
        2 => {
            let b = [bytes[0], bytes[1]];
            u64::from(if BIG { u16::from_be_bytes(b) } else { u16::from_le_bytes(b) })
        }
        4 => {
            let b = [bytes[0], bytes[1], bytes[2], bytes[3]];
            u64::from(if BIG { u32::from_be_bytes(b) } else { u32::from_le_bytes(b) })
        }
        _ => {
            let b = [bytes[0], bytes[1], bytes[2], bytes[3], bytes[4], bytes[5], bytes[6], bytes[7]];
            if BIG {
                u64::from_be_bytes(b)
            } else {
                u64::from_le_bytes(b)
            }
        }
    };
    P::from_bits(bits)
}

/// [`get`] for decoders: `None` where the bytes are no valid value of `P` (a boolean other than 0 or 1).
#[inline(always)]
pub(crate) fn get_valid<P: Primitive, const BIG: bool>(bytes: &[u8]) -> Option<P> {
    let value = get::<P, BIG>(bytes);
    if P::KIND == PrimKind::Bool {
        P::from_valid_bits(u64::from(bytes[0]))
    } else {
        Some(value)
    }
}

impl<const BIG: bool, const V2: bool> Reader<'_, BIG, V2> {
    const REPRESENTATION: Representation = representation(V2);

    /// Aligns and returns the next `len` bytes.
    #[inline(always)]
    fn take(&mut self, member: &'static str, align: usize, len: usize) -> Result<&[u8], DecodeError> {
        let start = Self::REPRESENTATION.align(self.pos, align);
        // `pos` never exceeds `buf.len()`, so `start + len` cannot overflow for in-memory lengths.
        let end = start + len;
        if end <= self.buf.len() {
            self.pos = end;
            Ok(&self.buf[start..end])
        } else {
            Err(truncated(member, start, len, self.buf.len()))
        }
    }

    fn u32(&mut self, member: &'static str) -> Result<u32, DecodeError> {
        let bytes = self.take(member, 4, 4)?;
        Ok(get::<u32, BIG>(bytes))
    }

    /// One primitive or a run of them: reads, and rejects invalid booleans where they are.
    #[inline(always)]
    fn primitives<P: Primitive>(&mut self, name: &'static str, items: &mut [P]) -> Result<(), DecodeError> {
        let start = Self::REPRESENTATION.align(self.pos, P::SIZE);
        let bytes = self.take(name, P::SIZE, items.len() * P::SIZE)?;
        for (k, (item, chunk)) in items.iter_mut().zip(bytes.chunks_exact(P::SIZE)).enumerate() {
            *item = match get_valid::<P, BIG>(chunk) {
                Some(v) => v,
                None => return Err(DecodeError::InvalidBool { member: name, offset: start + k, value: chunk[0] }),
            };
        }
        Ok(())
    }

    /// A sequence's element count, bounded by the bytes left (each element takes at least `min` bytes) before
    /// anything is allocated for it.
    fn count(&mut self, name: &'static str, min: usize) -> Result<usize, DecodeError> {
        let offset = Self::REPRESENTATION.align(self.pos, 4);
        let count = self.u32(name)?;
        let available = self.buf.len() - self.pos;
        if (count as usize).saturating_mul(min.max(1)) > available {
            return Err(DecodeError::BadSequenceLength { member: name, offset, count, available });
        }
        Ok(count as usize)
    }

    fn check_dheader(
        &self,
        member: &'static str,
        offset: usize,
        declared: u32,
        start: usize,
    ) -> Result<(), DecodeError> {
        let actual = self.pos - start;
        if actual == declared as usize {
            Ok(())
        } else {
            Err(DecodeError::BadDheader { member, offset, declared, actual })
        }
    }
}

impl<const BIG: bool, const V2: bool> VisitorMut for Reader<'_, BIG, V2> {
    type Error = DecodeError;

    #[inline(always)]
    fn primitive<P: Primitive>(&mut self, name: &'static str, value: &mut P) -> Result<(), DecodeError> {
        if P::KIND == PrimKind::Bool {
            return self.primitives(name, core::slice::from_mut(value));
        }
        let bytes = self.take(name, P::SIZE, P::SIZE)?;
        *value = get::<P, BIG>(bytes);
        Ok(())
    }

    #[inline(always)]
    fn primitive_array<P: Primitive>(&mut self, name: &'static str, items: &mut [P]) -> Result<(), DecodeError> {
        if P::KIND == PrimKind::Bool {
            return self.primitives(name, items);
        }
        let bytes = self.take(name, P::SIZE, items.len() * P::SIZE)?;
        for (item, chunk) in items.iter_mut().zip(bytes.chunks_exact(P::SIZE)) {
            *item = get::<P, BIG>(chunk);
        }
        Ok(())
    }

    #[inline(always)]
    fn structure<S: IdlStruct>(&mut self, _name: &'static str, value: &mut S) -> Result<(), DecodeError> {
        value.walk_mut(self)
    }

    fn struct_array<S: IdlStruct>(&mut self, name: &'static str, items: &mut [S]) -> Result<(), DecodeError> {
        if Self::REPRESENTATION.has_dheader() {
            let offset = Self::REPRESENTATION.align(self.pos, 4);
            let declared = self.u32(name)?;
            let start = self.pos;
            for item in items.iter_mut() {
                item.walk_mut(self)?;
            }
            self.check_dheader(name, offset, declared, start)
        } else {
            items.iter_mut().try_for_each(|item| item.walk_mut(self))
        }
    }

    fn struct_sequence<S: IdlStruct>(&mut self, name: &'static str, items: &mut Vec<S>) -> Result<(), DecodeError> {
        let repr = Self::REPRESENTATION;
        let dheader = if repr.has_dheader() { Some((repr.align(self.pos, 4), self.u32(name)?, 0)) } else { None };
        let dheader = dheader.map(|(offset, declared, _)| (offset, declared, self.pos));
        let count = self.count(name, S::CDR_MIN)?;
        items.clear();
        items.reserve(count);
        for _ in 0..count {
            let mut item = S::zeroed();
            item.walk_mut(self)?;
            items.push(item);
        }
        match dheader {
            Some((offset, declared, start)) => self.check_dheader(name, offset, declared, start),
            None => Ok(()),
        }
    }

    fn primitive_sequence<P: Primitive>(&mut self, name: &'static str, items: &mut Vec<P>) -> Result<(), DecodeError> {
        let count = self.count(name, P::SIZE)?;
        items.clear();
        if count > 0 {
            items.resize(count, P::from_bits(0));
            self.primitive_array(name, items)?;
        }
        Ok(())
    }

    fn string(&mut self, name: &'static str, value: &mut String) -> Result<(), DecodeError> {
        let offset = Self::REPRESENTATION.align(self.pos, 4);
        let len = self.count(name, 1)?;
        let fault = |reason| DecodeError::BadString { member: name, offset, reason };
        let Some(chars) = len.checked_sub(1) else { return Err(fault(StringFault::ZeroLength)) };
        let bytes = self.take(name, 1, len)?;
        if bytes[chars] != 0 {
            return Err(fault(StringFault::Unterminated));
        }
        match core::str::from_utf8(&bytes[..chars]) {
            Ok(text) => {
                value.clear();
                value.push_str(text);
                Ok(())
            }
            Err(e) => Err(fault(StringFault::NotUtf8 { at: e.valid_up_to() })),
        }
    }
}
