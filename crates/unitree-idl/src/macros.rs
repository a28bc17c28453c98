//! `idl_struct!`: declares a struct once and derives its reflection from that declaration.

/// Declares an IDL struct: the Rust struct (members public, `Default`, `Clone`, `Debug`,
/// `PartialEq`) and its [`IdlStruct`](crate::IdlStruct) implementation. Members are listed in
/// IDL order; that order is the wire order and the C struct order.
macro_rules! idl_struct {
    (
        $(#[$meta:meta])*
        $module:literal struct $name:ident {
            $( $(#[$fmeta:meta])* $field:ident : $ty:ty ),* $(,)?
        }
    ) => {
        $(#[$meta])*
        #[derive(Debug, Clone, PartialEq)]
        #[cfg_attr(feature = "arbitrary", derive(arbitrary::Arbitrary))]
        pub struct $name {
            $( $(#[$fmeta])* pub $field: $ty, )*
        }

        impl $crate::reflect::Field for $name {
            const C_ALIGN: usize = {
                let mut a = 1;
                $( a = $crate::reflect::max(a, <$ty as $crate::reflect::Field>::C_ALIGN); )*
                a
            };
            const C_SIZE: usize = {
                let mut off = 0;
                $( off = $crate::reflect::align_up(off, <$ty as $crate::reflect::Field>::C_ALIGN)
                    + <$ty as $crate::reflect::Field>::C_SIZE; )*
                $crate::reflect::align_up(off, <Self as $crate::reflect::Field>::C_ALIGN)
            };
            const CDR_MIN: usize = 0 $( + <$ty as $crate::reflect::Field>::CDR_MIN )*;
            const HAS_SEQUENCE: bool = false $( || <$ty as $crate::reflect::Field>::HAS_SEQUENCE )*;
            const EVERY_BYTE_VALID: bool = true $( && <$ty as $crate::reflect::Field>::EVERY_BYTE_VALID )*;
            fn zeroed() -> Self {
                Self { $( $field: <$ty as $crate::reflect::Field>::zeroed(), )* }
            }
            #[inline(always)]
            fn visit<V: $crate::reflect::Visitor>(&self, name: &'static str, v: &mut V) {
                v.structure(name, self)
            }
            #[inline(always)]
            fn visit_mut<V: $crate::reflect::VisitorMut>(&mut self, name: &'static str, v: &mut V) -> Result<(), V::Error> {
                v.structure(name, self)
            }
        }

        impl Default for $name {
            /// All members zero, as the C++ SDK's default constructor leaves them.
            fn default() -> Self {
                <Self as $crate::reflect::Field>::zeroed()
            }
        }

        impl $crate::reflect::Element for $name {
            #[inline(always)]
            fn visit_array<V: $crate::reflect::Visitor>(items: &[Self], name: &'static str, v: &mut V) {
                v.struct_array(name, items)
            }
            #[inline(always)]
            fn visit_array_mut<V: $crate::reflect::VisitorMut>(items: &mut [Self], name: &'static str, v: &mut V) -> Result<(), V::Error> {
                v.struct_array(name, items)
            }
            #[inline(always)]
            fn visit_sequence<V: $crate::reflect::Visitor>(items: &[Self], name: &'static str, v: &mut V) {
                v.struct_sequence(name, items)
            }
            #[inline(always)]
            fn visit_sequence_mut<V: $crate::reflect::VisitorMut>(items: &mut Vec<Self>, name: &'static str, v: &mut V) -> Result<(), V::Error> {
                v.struct_sequence(name, items)
            }
        }

        impl $crate::reflect::IdlStruct for $name {
            const IDL_NAME: &'static str = stringify!($name);
            const DDS_TYPE_NAME: &'static str = concat!($module, "::msg::dds_::", stringify!($name));
            const MEMBERS: &'static [&'static str] = &[$( $crate::reflect::member_name(stringify!($field)) ),*];
            #[inline(always)]
            fn walk<V: $crate::reflect::Visitor>(&self, v: &mut V) {
                $( <$ty as $crate::reflect::Field>::visit(&self.$field, { const NAME: &str = $crate::reflect::member_name(stringify!($field)); NAME }, v); )*
            }
            #[inline(always)]
            fn walk_mut<V: $crate::reflect::VisitorMut>(&mut self, v: &mut V) -> Result<(), V::Error> {
                $( <$ty as $crate::reflect::Field>::visit_mut(&mut self.$field, { const NAME: &str = $crate::reflect::member_name(stringify!($field)); NAME }, v)?; )*
                Ok(())
            }
        }
    };
}

pub(crate) use idl_struct;
