//! Where every member of a fixed-layout type sits in one representation, computed once by
//! walking the type's reflection with the codec's own alignment and DHEADER rules
//! ([`Representation::align`], [`Representation::has_dheader`]).

use crate::cdr::{self, DecodeError, Representation};
use unitree_idl::{IdlStruct, Primitive, Visitor};

/// Payload offsets of a fixed-layout type (no sequences) in one representation, and what the
/// decoder would check, in the decoder's order, so that [`view`](super::view()) reports exactly the
/// error [`cdr::decode`] reports.
#[derive(Debug)]
pub struct Layout {
    /// Payload offset of every primitive and primitive array (a "leaf"), in declaration order
    /// (depth first). Offsets are per instance: CDR structs have no alignment of their own, so
    /// element 0 of an array can be padded differently from the others.
    leaves: Vec<u32>,
    /// Every read the decoder makes (leaves and DHEADERs), in its order; ends never decrease.
    reads: Vec<Read>,
    /// DHEADERs in the order the decoder checks them: when the array they frame ends.
    dheaders: Vec<Dheader>,
    /// Payload length (header and declared padding excluded): the only valid one.
    len: usize,
}

#[derive(Debug, Clone, Copy)]
struct Read {
    member: &'static str,
    start: usize,
    len: usize,
}

#[derive(Debug, Clone, Copy)]
struct Dheader {
    member: &'static str,
    /// Payload offset of the DHEADER itself.
    offset: usize,
    /// Bytes of the elements it frames (fixed for a fixed-layout type).
    actual: usize,
    /// Payload offset just after the last element.
    end: usize,
}

impl Layout {
    /// Walks `T`'s reflection once. `T` must have no sequence (checked where views are declared).
    pub fn of<T: IdlStruct>(representation: Representation) -> Layout {
        let mut walk = Walk {
            representation,
            pos: 0,
            layout: Layout { leaves: Vec::new(), reads: Vec::new(), dheaders: Vec::new(), len: 0 },
        };
        T::zeroed().walk(&mut walk);
        walk.layout.len = walk.pos;
        walk.layout
    }

    /// Payload length of every valid sample in this representation.
    pub fn payload_len(&self) -> usize {
        self.len
    }

    /// Payload offsets of the DHEADERs (XCDR2), in the order they are checked.
    pub fn dheader_offsets(&self) -> impl Iterator<Item = usize> + '_ {
        self.dheaders.iter().map(|d| d.offset)
    }

    /// Payload offset of every leaf (primitive or primitive array), in declaration order.
    pub fn leaf_offsets(&self) -> &[u32] {
        &self.leaves
    }

    /// Accepts `body` (payload without declared padding) iff [`cdr::decode`] accepts it, with the
    /// same error otherwise. Valid samples cost one length comparison plus one comparison per
    /// DHEADER (XCDR2).
    #[inline]
    pub(crate) fn check(&self, body: &[u8], big: bool) -> Result<(), DecodeError> {
        if body.len() == self.len && self.dheaders.iter().all(|d| d.declared(body, big) as usize == d.actual) {
            Ok(())
        } else {
            Err(self.diagnose(body, big))
        }
    }

    /// The decoder's first error on an invalid `body`. The decoder reads in walk order and checks
    /// a DHEADER right after its array's last element, so: a wrong DHEADER whose array lies
    /// wholly inside the input comes first (in check order); then, if the input is short, the
    /// first read that does not fit; then trailing bytes.
    #[cold]
    #[inline(never)]
    fn diagnose(&self, body: &[u8], big: bool) -> DecodeError {
        let len = body.len();
        for d in self.dheaders.iter().filter(|d| d.end <= len) {
            let declared = d.declared(body, big);
            if declared as usize != d.actual {
                return DecodeError::BadDheader { member: d.member, offset: d.offset, declared, actual: d.actual };
            }
        }
        if len > self.len {
            return cdr::trailing(self.len, len);
        }
        // Short input: the last read ends at `self.len > len`, so a read that does not fit exists.
        let first_short = self.reads.partition_point(|r| r.start + r.len <= len);
        match self.reads.get(first_short) {
            Some(r) => cdr::truncated(r.member, r.start, r.len, len),
            // Unreachable for a non-empty type; an empty one has no valid short input either.
            None => cdr::trailing(len.min(self.len), len),
        }
    }
}

impl Dheader {
    /// The declared length (`end <= body.len()` holds wherever this is called).
    #[inline(always)]
    fn declared(&self, body: &[u8], big: bool) -> u32 {
        super::read_value::<u32>(body, self.offset, big)
    }
}

/// Position-tracking visitor: the reader's walk without the bytes.
struct Walk {
    representation: Representation,
    pos: usize,
    layout: Layout,
}

impl Walk {
    /// Records a read of `len` bytes aligned for a primitive of `size` bytes; returns its start.
    fn read(&mut self, member: &'static str, size: usize, len: usize) -> usize {
        let start = self.representation.align(self.pos, size);
        self.layout.reads.push(Read { member, start, len });
        self.pos = start + len;
        start
    }

    fn leaf(&mut self, member: &'static str, size: usize, len: usize) {
        let start = self.read(member, size, len);
        // Fixed SDK2 types are a few kilobytes; u32 keeps the offset table dense.
        self.layout.leaves.push(u32::try_from(start).unwrap_or(u32::MAX));
    }
}

impl Visitor for Walk {
    fn primitive<P: Primitive>(&mut self, name: &'static str, _value: &P) {
        self.leaf(name, P::SIZE, P::SIZE);
    }

    fn primitive_array<P: Primitive>(&mut self, name: &'static str, items: &[P]) {
        self.leaf(name, P::SIZE, items.len() * P::SIZE);
    }

    fn structure<S: IdlStruct>(&mut self, _name: &'static str, value: &S) {
        value.walk(self);
    }

    fn struct_array<S: IdlStruct>(&mut self, name: &'static str, items: &[S]) {
        if self.representation.has_dheader() {
            // A DHEADER is a uint32.
            let offset = self.read(name, 4, 4);
            let start = self.pos;
            items.iter().for_each(|item| item.walk(self));
            self.layout.dheaders.push(Dheader { member: name, offset, actual: self.pos - start, end: self.pos });
        } else {
            items.iter().for_each(|item| item.walk(self));
        }
    }

    /// Never reached: views are declared only for types without sequences (a compile-time check).
    fn struct_sequence<S: IdlStruct>(&mut self, _name: &'static str, _items: &[S]) {}
    /// Never reached, as above.
    fn primitive_sequence<P: Primitive>(&mut self, _name: &'static str, _items: &[P]) {}
    /// Never reached, as above (strings have no fixed size).
    fn string(&mut self, _name: &'static str, _value: &str) {}
}
