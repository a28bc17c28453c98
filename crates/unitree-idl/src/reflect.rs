//! Reflection over IDL structs: the one description of member order and types.
//!
//! A struct lists its members with [`Field`]; a [`Visitor`] (read-only) or [`VisitorMut`]
//! (fills in values, may fail) is walked over them. Members are primitives, fixed arrays of
//! primitives or structs, nested structs, unbounded sequences of primitives or structs, and
//! unbounded strings: exactly the shapes the SDK2 low-level IDL (`unitree_hg`, `unitree_go`)
//! and its RPC types (`unitree_api`) use.

/// The primitive kinds used by the SDK2 IDL.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PrimKind {
    /// IDL `boolean`: one byte, 0 or 1 on the wire.
    Bool,
    /// IDL `octet` / `uint8`.
    U8,
    /// IDL `short` / `int16`.
    I16,
    /// IDL `unsigned short` / `uint16`.
    U16,
    /// IDL `long` / `int32`.
    I32,
    /// IDL `unsigned long` / `uint32`.
    U32,
    /// IDL `long long` / `int64`.
    I64,
    /// IDL `float`: IEEE-754 single precision.
    F32,
}

/// A primitive IDL type with a fixed size and byte representation.
pub trait Primitive: Copy + Default + PartialEq + core::fmt::Debug + 'static {
    /// Which IDL primitive this is.
    const KIND: PrimKind;
    /// Size in bytes; also its natural alignment (in C, and in CDR up to the representation's cap).
    const SIZE: usize;
    /// Raw bits, zero-extended (floats: their IEEE-754 bit pattern).
    fn to_bits(self) -> u64;
    /// Inverse of [`Primitive::to_bits`]; upper bits beyond `SIZE` are ignored.
    fn from_bits(bits: u64) -> Self;
    /// The value of `bits` if they are a valid encoding of this type: every pattern is, except
    /// for `boolean` (only 0 and 1). Decoders call this; for the other types it folds away.
    #[inline(always)]
    fn from_valid_bits(bits: u64) -> Option<Self> {
        Some(Self::from_bits(bits))
    }
}

macro_rules! primitive {
    ($t:ty, $kind:ident, $to:expr, $from:expr $(, $valid:expr)?) => {
        impl Primitive for $t {
            const KIND: PrimKind = PrimKind::$kind;
            const SIZE: usize = core::mem::size_of::<$t>();
            #[inline(always)]
            fn to_bits(self) -> u64 {
                #[allow(clippy::redundant_closure_call)]
                ($to)(self)
            }
            #[inline(always)]
            fn from_bits(bits: u64) -> Self {
                #[allow(clippy::redundant_closure_call)]
                ($from)(bits)
            }
            $(
            #[inline(always)]
            fn from_valid_bits(bits: u64) -> Option<Self> {
                #[allow(clippy::redundant_closure_call)]
                ($valid)(bits)
            }
            )?
        }
        impl Field for $t {
            const C_ALIGN: usize = <$t as Primitive>::SIZE;
            const C_SIZE: usize = <$t as Primitive>::SIZE;
            const CDR_MIN: usize = <$t as Primitive>::SIZE;
            const HAS_SEQUENCE: bool = false;
            const EVERY_BYTE_VALID: bool = !matches!(<$t as Primitive>::KIND, PrimKind::Bool);
            fn zeroed() -> Self {
                <$t as Primitive>::from_bits(0)
            }
            #[inline(always)]
            fn visit<V: Visitor>(&self, name: &'static str, v: &mut V) {
                v.primitive(name, self)
            }
            #[inline(always)]
            fn visit_mut<V: VisitorMut>(&mut self, name: &'static str, v: &mut V) -> Result<(), V::Error> {
                v.primitive(name, self)
            }
        }
        impl Element for $t {
            #[inline(always)]
            fn visit_array<V: Visitor>(items: &[Self], name: &'static str, v: &mut V) {
                v.primitive_array(name, items)
            }
            #[inline(always)]
            fn visit_array_mut<V: VisitorMut>(
                items: &mut [Self],
                name: &'static str,
                v: &mut V,
            ) -> Result<(), V::Error> {
                v.primitive_array(name, items)
            }
            #[inline(always)]
            fn visit_sequence<V: Visitor>(items: &[Self], name: &'static str, v: &mut V) {
                v.primitive_sequence(name, items)
            }
            #[inline(always)]
            fn visit_sequence_mut<V: VisitorMut>(
                items: &mut Vec<Self>,
                name: &'static str,
                v: &mut V,
            ) -> Result<(), V::Error> {
                v.primitive_sequence(name, items)
            }
        }
    };
}

primitive!(bool, Bool, |x: bool| u64::from(x), |b: u64| b & 1 != 0, |b: u64| match b & 0xff {
    0 => Some(false),
    1 => Some(true),
    _ => None,
});
primitive!(u8, U8, |x: u8| u64::from(x), |b: u64| b as u8);
primitive!(i16, I16, |x: i16| u64::from(x as u16), |b: u64| b as u16 as i16);
primitive!(u16, U16, |x: u16| u64::from(x), |b: u64| b as u16);
primitive!(i32, I32, |x: i32| u64::from(x as u32), |b: u64| b as u32 as i32);
primitive!(u32, U32, |x: u32| u64::from(x), |b: u64| b as u32);
primitive!(i64, I64, |x: i64| x as u64, |b: u64| b as i64);
primitive!(f32, F32, |x: f32| u64::from(x.to_bits()), |b: u64| f32::from_bits(b as u32));

/// Anything that can be a struct member. Implemented for primitives, IDL structs, fixed arrays
/// of [`Element`]s, `Vec` (IDL `sequence<>`) of [`Element`]s and `String` (IDL `string`).
pub trait Field {
    /// Alignment in the C struct image (natural alignment).
    const C_ALIGN: usize;
    /// Size in the C struct image including tail padding (sequences have none: 0).
    const C_SIZE: usize;
    /// Fewest bytes this member can take in CDR, ignoring alignment: bounds sequence lengths
    /// before anything is allocated.
    const CDR_MIN: usize;
    /// Whether the member contains a sequence or string anywhere (then it has no fixed CDR size).
    const HAS_SEQUENCE: bool;
    /// Whether every byte pattern of a member's fixed size decodes (false for `boolean`, whose
    /// byte must be 0 or 1). Zero-copy views need this and no sequence.
    const EVERY_BYTE_VALID: bool;
    /// The all-zero value (what the C++ SDK's default constructor gives). `Default` cannot
    /// serve: the standard library implements it only for arrays of up to 32 elements.
    fn zeroed() -> Self
    where
        Self: Sized;
    /// Hands this member, named `name`, to the visitor method for its shape.
    fn visit<V: Visitor>(&self, name: &'static str, v: &mut V);
    /// Hands this member, named `name`, to the visitor method for its shape, to be assigned.
    fn visit_mut<V: VisitorMut>(&mut self, name: &'static str, v: &mut V) -> Result<(), V::Error>;
}

/// An element type of an array or sequence: dispatches to the visitor method for its shape.
pub trait Element: Field + Sized {
    /// Visits a fixed array member of this element type.
    fn visit_array<V: Visitor>(items: &[Self], name: &'static str, v: &mut V);
    /// Visits a fixed array member of this element type, to be assigned.
    fn visit_array_mut<V: VisitorMut>(items: &mut [Self], name: &'static str, v: &mut V) -> Result<(), V::Error>;
    /// Visits a sequence member of this element type.
    fn visit_sequence<V: Visitor>(items: &[Self], name: &'static str, v: &mut V);
    /// Visits a sequence member of this element type, to be assigned (the visitor sets its length).
    fn visit_sequence_mut<V: VisitorMut>(items: &mut Vec<Self>, name: &'static str, v: &mut V) -> Result<(), V::Error>;
}

impl<T: Element, const N: usize> Field for [T; N] {
    const C_ALIGN: usize = T::C_ALIGN;
    const C_SIZE: usize = T::C_SIZE * N;
    const CDR_MIN: usize = T::CDR_MIN * N;
    const HAS_SEQUENCE: bool = T::HAS_SEQUENCE;
    const EVERY_BYTE_VALID: bool = T::EVERY_BYTE_VALID;
    fn zeroed() -> Self {
        core::array::from_fn(|_| T::zeroed())
    }
    #[inline(always)]
    fn visit<V: Visitor>(&self, name: &'static str, v: &mut V) {
        T::visit_array(self, name, v)
    }
    #[inline(always)]
    fn visit_mut<V: VisitorMut>(&mut self, name: &'static str, v: &mut V) -> Result<(), V::Error> {
        T::visit_array_mut(self, name, v)
    }
}

impl<T: Element> Field for Vec<T> {
    // A std::vector in the C++ SDK: no flat C image; types holding one carry no CRC.
    const C_ALIGN: usize = 1;
    const C_SIZE: usize = 0;
    const CDR_MIN: usize = 4;
    const HAS_SEQUENCE: bool = true;
    const EVERY_BYTE_VALID: bool = T::EVERY_BYTE_VALID;
    fn zeroed() -> Self {
        Vec::new()
    }
    #[inline(always)]
    fn visit<V: Visitor>(&self, name: &'static str, v: &mut V) {
        T::visit_sequence(self, name, v)
    }
    #[inline(always)]
    fn visit_mut<V: VisitorMut>(&mut self, name: &'static str, v: &mut V) -> Result<(), V::Error> {
        T::visit_sequence_mut(self, name, v)
    }
}

impl Field for String {
    // A std::string in the C++ SDK: no flat C image, like a sequence.
    const C_ALIGN: usize = 1;
    const C_SIZE: usize = 0;
    /// The length word and the terminating NUL.
    const CDR_MIN: usize = 5;
    const HAS_SEQUENCE: bool = true;
    const EVERY_BYTE_VALID: bool = false;
    fn zeroed() -> Self {
        String::new()
    }
    #[inline(always)]
    fn visit<V: Visitor>(&self, name: &'static str, v: &mut V) {
        v.string(name, self)
    }
    #[inline(always)]
    fn visit_mut<V: VisitorMut>(&mut self, name: &'static str, v: &mut V) -> Result<(), V::Error> {
        v.string(name, self)
    }
}

/// An IDL struct (`@final`, keyless, as every SDK2 type is).
pub trait IdlStruct: Element + Clone + core::fmt::Debug + 'static {
    /// IDL name without module, e.g. `LowCmd_`.
    const IDL_NAME: &'static str;
    /// Fully qualified DDS type name, e.g. `unitree_hg::msg::dds_::LowCmd_`.
    const DDS_TYPE_NAME: &'static str;
    /// Member names in declaration order.
    const MEMBERS: &'static [&'static str];
    /// Walk the members in declaration order.
    fn walk<V: Visitor>(&self, v: &mut V);
    /// Walk the members in declaration order, letting the visitor assign them.
    fn walk_mut<V: VisitorMut>(&mut self, v: &mut V) -> Result<(), V::Error>;
}

/// Read-only walk over a value.
pub trait Visitor {
    /// A primitive member.
    fn primitive<P: Primitive>(&mut self, name: &'static str, value: &P);
    /// A fixed array of primitives.
    fn primitive_array<P: Primitive>(&mut self, name: &'static str, items: &[P]);
    /// A nested struct; call [`IdlStruct::walk`] on it to descend.
    fn structure<S: IdlStruct>(&mut self, name: &'static str, value: &S);
    /// A fixed array of structs.
    fn struct_array<S: IdlStruct>(&mut self, name: &'static str, items: &[S]);
    /// A sequence of structs.
    fn struct_sequence<S: IdlStruct>(&mut self, name: &'static str, items: &[S]);
    /// A sequence of primitives.
    fn primitive_sequence<P: Primitive>(&mut self, name: &'static str, items: &[P]);
    /// A string member.
    fn string(&mut self, name: &'static str, value: &str);
}

/// Walk that assigns each member (decoding, parsing JSON, generating values).
pub trait VisitorMut {
    /// Why a member could not be assigned; the walk stops at the first error.
    type Error;
    /// Assigns a primitive member.
    fn primitive<P: Primitive>(&mut self, name: &'static str, value: &mut P) -> Result<(), Self::Error>;
    /// Assigns every element of a fixed array of primitives.
    fn primitive_array<P: Primitive>(&mut self, name: &'static str, items: &mut [P]) -> Result<(), Self::Error>;
    /// A nested struct; call [`IdlStruct::walk_mut`] on it to descend.
    fn structure<S: IdlStruct>(&mut self, name: &'static str, value: &mut S) -> Result<(), Self::Error>;
    /// Assigns every element of a fixed array of structs.
    fn struct_array<S: IdlStruct>(&mut self, name: &'static str, items: &mut [S]) -> Result<(), Self::Error>;
    /// Fills a sequence of structs (its length included).
    fn struct_sequence<S: IdlStruct>(&mut self, name: &'static str, items: &mut Vec<S>) -> Result<(), Self::Error>;
    /// Fills a sequence of primitives (its length included).
    fn primitive_sequence<P: Primitive>(&mut self, name: &'static str, items: &mut Vec<P>) -> Result<(), Self::Error>;
    /// Assigns a string member.
    fn string(&mut self, name: &'static str, value: &mut String) -> Result<(), Self::Error>;
}

/// Round `offset` up to a multiple of `align` (a power of two).
pub const fn align_up(offset: usize, align: usize) -> usize {
    (offset + align - 1) & !(align - 1)
}

/// Larger of two sizes, usable in constant expressions.
pub const fn max(a: usize, b: usize) -> usize {
    if a > b {
        a
    } else {
        b
    }
}

/// IDL member name of a Rust field identifier: strips the `r#` of raw identifiers (`r#fn`).
pub const fn member_name(ident: &'static str) -> &'static str {
    let bytes = ident.as_bytes();
    if bytes.len() > 2 && bytes[0] == b'r' && bytes[1] == b'#' {
        let (_, rest) = bytes.split_at(2);
        match core::str::from_utf8(rest) {
            Ok(name) => name,
            Err(_) => ident,
        }
    } else {
        ident
    }
}
