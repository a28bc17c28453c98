//! Reflection over IDL structs: the one description of member order and types.
//!
//! A struct lists its members with [`Field`]; a [`Visitor`] (read-only) or [`VisitorMut`]
//! (fills in values, may fail) is walked over them. Members are primitives, fixed arrays of
//! primitives or structs, nested structs, and unbounded sequences of structs: exactly the
//! shapes the SDK2 low-level IDL uses.

/// The primitive kinds used by the SDK2 low-level IDL.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PrimKind {
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
}

/// A primitive IDL type with a fixed size and byte representation.
pub trait Primitive: Copy + Default + PartialEq + core::fmt::Debug + 'static {
    const KIND: PrimKind;
    /// Size in bytes; also its natural alignment (in C and in CDR).
    const SIZE: usize;
    /// Raw bits, zero-extended (floats: their IEEE-754 bit pattern).
    fn to_bits(self) -> u32;
    /// Inverse of [`Primitive::to_bits`]; upper bits beyond `SIZE` are ignored.
    fn from_bits(bits: u32) -> Self;
}

macro_rules! primitive {
    ($t:ty, $kind:ident, $to:expr, $from:expr) => {
        impl Primitive for $t {
            const KIND: PrimKind = PrimKind::$kind;
            const SIZE: usize = core::mem::size_of::<$t>();
            #[inline(always)]
            fn to_bits(self) -> u32 {
                #[allow(clippy::redundant_closure_call)]
                ($to)(self)
            }
            #[inline(always)]
            fn from_bits(bits: u32) -> Self {
                #[allow(clippy::redundant_closure_call)]
                ($from)(bits)
            }
        }
        impl Field for $t {
            const C_ALIGN: usize = <$t as Primitive>::SIZE;
            const C_SIZE: usize = <$t as Primitive>::SIZE;
            const CDR_MIN: usize = <$t as Primitive>::SIZE;
            const HAS_SEQUENCE: bool = false;
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
        }
    };
}

primitive!(u8, U8, |x: u8| u32::from(x), |b: u32| b as u8);
primitive!(i16, I16, |x: i16| u32::from(x as u16), |b: u32| b as u16 as i16);
primitive!(u16, U16, |x: u16| u32::from(x), |b: u32| b as u16);
primitive!(i32, I32, |x: i32| x as u32, |b: u32| b as i32);
primitive!(u32, U32, |x: u32| x, |b: u32| b);
primitive!(f32, F32, |x: f32| x.to_bits(), f32::from_bits);

/// Anything that can be a struct member. Implemented for primitives, IDL structs, fixed arrays
/// of [`Element`]s and `Vec` (IDL `sequence<>`) of structs.
pub trait Field {
    /// Alignment in the C struct image (natural alignment).
    const C_ALIGN: usize;
    /// Size in the C struct image including tail padding (sequences have none: 0).
    const C_SIZE: usize;
    /// Fewest bytes this member can take in CDR, ignoring alignment: bounds sequence lengths
    /// before anything is allocated.
    const CDR_MIN: usize;
    /// Whether the member contains a sequence anywhere (then it has no fixed CDR size).
    const HAS_SEQUENCE: bool;
    /// The all-zero value (what the C++ SDK's default constructor gives). `Default` cannot
    /// serve: the standard library implements it only for arrays of up to 32 elements.
    fn zeroed() -> Self
    where
        Self: Sized;
    fn visit<V: Visitor>(&self, name: &'static str, v: &mut V);
    fn visit_mut<V: VisitorMut>(&mut self, name: &'static str, v: &mut V) -> Result<(), V::Error>;
}

/// An element type of an array or sequence: dispatches to the visitor method for its shape.
pub trait Element: Field + Sized {
    fn visit_array<V: Visitor>(items: &[Self], name: &'static str, v: &mut V);
    fn visit_array_mut<V: VisitorMut>(items: &mut [Self], name: &'static str, v: &mut V) -> Result<(), V::Error>;
}

impl<T: Element, const N: usize> Field for [T; N] {
    const C_ALIGN: usize = T::C_ALIGN;
    const C_SIZE: usize = T::C_SIZE * N;
    const CDR_MIN: usize = T::CDR_MIN * N;
    const HAS_SEQUENCE: bool = T::HAS_SEQUENCE;
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

impl<S: IdlStruct> Field for Vec<S> {
    // A std::vector in the C++ SDK: no flat C image; types holding one carry no CRC.
    const C_ALIGN: usize = 1;
    const C_SIZE: usize = 0;
    const CDR_MIN: usize = 4;
    const HAS_SEQUENCE: bool = true;
    fn zeroed() -> Self {
        Vec::new()
    }
    fn visit<V: Visitor>(&self, name: &'static str, v: &mut V) {
        v.struct_sequence(name, self)
    }
    fn visit_mut<V: VisitorMut>(&mut self, name: &'static str, v: &mut V) -> Result<(), V::Error> {
        v.struct_sequence(name, self)
    }
}

/// An IDL struct (`@final`, keyless, as every SDK2 low-level type is).
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
    fn primitive<P: Primitive>(&mut self, name: &'static str, value: &P);
    fn primitive_array<P: Primitive>(&mut self, name: &'static str, items: &[P]);
    fn structure<S: IdlStruct>(&mut self, name: &'static str, value: &S);
    fn struct_array<S: IdlStruct>(&mut self, name: &'static str, items: &[S]);
    fn struct_sequence<S: IdlStruct>(&mut self, name: &'static str, items: &[S]);
}

/// Walk that assigns each member (decoding, parsing JSON, generating values).
pub trait VisitorMut {
    type Error;
    fn primitive<P: Primitive>(&mut self, name: &'static str, value: &mut P) -> Result<(), Self::Error>;
    fn primitive_array<P: Primitive>(&mut self, name: &'static str, items: &mut [P]) -> Result<(), Self::Error>;
    fn structure<S: IdlStruct>(&mut self, name: &'static str, value: &mut S) -> Result<(), Self::Error>;
    fn struct_array<S: IdlStruct>(&mut self, name: &'static str, items: &mut [S]) -> Result<(), Self::Error>;
    fn struct_sequence<S: IdlStruct>(&mut self, name: &'static str, items: &mut Vec<S>) -> Result<(), Self::Error>;
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
