//! Zero-copy views of samples of fixed-layout types (every SDK2 low-level type without a
//! sequence: hg/go `LowCmd`, `LowState` and their parts).
//!
//! [`view`] checks a sample exactly as [`crate::decode`] does (same [`DecodeError`] for the same
//! bytes) but builds nothing: a fixed-layout type has one valid payload length per
//! representation, so validation is a length comparison (plus the DHEADER values in XCDR2).
//! Accessors named after the IDL members then read their bytes on demand at offsets computed
//! once per type and representation ([`Layout`], cached) and cannot fail: every offset was
//! proven in bounds when the view was built.
//!
//! ```
//! use lowlevel_codec::{encode, view, Encoding};
//! use unitree_idl::hg;
//!
//! let mut state = hg::LowState_ { tick: 42, ..Default::default() };
//! state.motor_state[3].q = 0.25;
//! let bytes = encode(&state, Encoding::UNITREE);
//!
//! let v = view::<hg::LowState_>(&bytes)?;
//! assert_eq!(v.tick(), 42);
//! assert_eq!(v.imu_state().quaternion(), [0.0; 4]);
//! let q: Vec<f32> = v.motor_state().iter().map(|m| m.q()).collect();
//! assert_eq!(q[3], 0.25);
//! assert_eq!(v.to_owned(), state);
//! # Ok::<(), lowlevel_codec::DecodeError>(())
//! ```

mod layout;

pub mod go;
pub mod hg;

pub use layout::Layout;

use crate::cdr::{self, split_sample, DecodeError, Decoded, Encoding, Endianness, Representation};
use std::marker::PhantomData;
use std::sync::OnceLock;
use unitree_idl::{IdlStruct, Primitive};

/// A fixed-layout IDL struct (no sequences) with a generated view, [`Self::View`].
pub trait Viewable: IdlStruct {
    /// The view of a whole sample of this type.
    type View<'a>: StructView<'a, Owned = Self>;

    /// Per-representation layout cache of this type (XCDR1, XCDR2).
    #[doc(hidden)]
    fn layout_cache() -> &'static [OnceLock<Layout>; 2];

    /// The layout of this type in `representation`, computed on first use.
    fn layout(representation: Representation) -> &'static Layout {
        Self::layout_cache()[representation.index()].get_or_init(|| Layout::of::<Self>(representation))
    }
}

/// A view of one struct instance inside a sample.
pub trait StructView<'a>: Copy + core::fmt::Debug + 'a {
    /// The struct it views.
    type Owned: IdlStruct;
    /// Leaves (primitives and primitive arrays) of [`Self::Owned`]: its share of
    /// [`Layout::leaf_offsets`].
    const LEAVES: usize;
    /// The view over `cursor`, whose leaf offsets are exactly this instance's.
    fn at(cursor: Cursor<'a>) -> Self;
    /// The cursor it was built from.
    fn cursor(&self) -> Cursor<'a>;
    /// The owned value (what the generated inherent `to_owned` returns).
    fn owned(&self) -> Self::Owned;
}

/// A validated payload, the byte order and the leaf offsets of one struct instance in it.
#[derive(Clone, Copy)]
pub struct Cursor<'a> {
    body: &'a [u8],
    leaves: &'a [u32],
    big: bool,
}

impl core::fmt::Debug for Cursor<'_> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Cursor")
            .field("payload_len", &self.body.len())
            .field("leaves", &self.leaves.len())
            .field("big_endian", &self.big)
            .finish()
    }
}

impl<'a> Cursor<'a> {
    /// The value of leaf `leaf` (a primitive or a primitive array).
    #[inline(always)]
    fn value<V: Value>(self, leaf: usize) -> V {
        V::read(self.body, self.leaves[leaf] as usize, self.big)
    }

    /// The cursor of a nested instance: `count` leaves from `first`.
    #[inline(always)]
    fn sub(self, first: usize, count: usize) -> Cursor<'a> {
        Cursor { leaves: &self.leaves[first..first + count], ..self }
    }
}

/// A primitive at `at` in `body`, through the codec's one byte-to-value conversion.
#[inline(always)]
fn read_value<P: Primitive>(body: &[u8], at: usize, big: bool) -> P {
    let bytes = &body[at..at + P::SIZE];
    if big {
        cdr::get::<P, true>(bytes)
    } else {
        cdr::get::<P, false>(bytes)
    }
}

/// The owned value of the instance under `cursor`: one reflection walk that assigns every leaf
/// from its precomputed offset (no alignment arithmetic, no bounds errors: both were settled
/// when the layout was built and the sample validated).
pub(crate) fn fill<S: IdlStruct>(cursor: Cursor<'_>) -> S {
    fn run<S: IdlStruct, const BIG: bool>(cursor: Cursor<'_>) -> S {
        let mut value = S::zeroed();
        let mut fill = Fill::<BIG> { body: cursor.body, leaves: cursor.leaves.iter() };
        match value.walk_mut(&mut fill) {
            Ok(()) => value,
            Err(never) => match never {},
        }
    }
    if cursor.big {
        run::<S, true>(cursor)
    } else {
        run::<S, false>(cursor)
    }
}

struct Fill<'a, const BIG: bool> {
    body: &'a [u8],
    leaves: core::slice::Iter<'a, u32>,
}

impl<const BIG: bool> Fill<'_, BIG> {
    /// The next leaf's `len` bytes (`len` is what the layout walk recorded for it).
    #[inline(always)]
    fn next(&mut self, len: usize) -> &[u8] {
        // The layout has exactly one offset per leaf; a missing one would read as offset 0
        // and be caught by the view tests, never by a panic here.
        let at = self.leaves.next().map_or(0, |&at| at as usize);
        &self.body[at..at + len]
    }
}

impl<const BIG: bool> unitree_idl::VisitorMut for Fill<'_, BIG> {
    type Error = core::convert::Infallible;

    #[inline(always)]
    fn primitive<P: Primitive>(&mut self, _name: &'static str, value: &mut P) -> Result<(), Self::Error> {
        *value = cdr::get::<P, BIG>(self.next(P::SIZE));
        Ok(())
    }

    #[inline(always)]
    fn primitive_array<P: Primitive>(&mut self, _name: &'static str, items: &mut [P]) -> Result<(), Self::Error> {
        let bytes = self.next(items.len() * P::SIZE);
        for (item, chunk) in items.iter_mut().zip(bytes.chunks_exact(P::SIZE)) {
            *item = cdr::get::<P, BIG>(chunk);
        }
        Ok(())
    }

    #[inline(always)]
    fn structure<S: IdlStruct>(&mut self, _name: &'static str, value: &mut S) -> Result<(), Self::Error> {
        value.walk_mut(self)
    }

    fn struct_array<S: IdlStruct>(&mut self, _name: &'static str, items: &mut [S]) -> Result<(), Self::Error> {
        items.iter_mut().try_for_each(|item| item.walk_mut(self))
    }

    /// Never reached: views exist only for types without sequences.
    fn struct_sequence<S: IdlStruct>(&mut self, _name: &'static str, _items: &mut Vec<S>) -> Result<(), Self::Error> {
        Ok(())
    }
    /// Never reached, as above.
    fn primitive_sequence<P: Primitive>(
        &mut self,
        _name: &'static str,
        _items: &mut Vec<P>,
    ) -> Result<(), Self::Error> {
        Ok(())
    }
    /// Never reached, as above.
    fn string(&mut self, _name: &'static str, _value: &mut String) -> Result<(), Self::Error> {
        Ok(())
    }
}

/// What a leaf accessor returns: a primitive, or a primitive array by value.
trait Value: Sized {
    fn read(body: &[u8], at: usize, big: bool) -> Self;
}

macro_rules! value {
    ($($p:ty),*) => {$(
        impl Value for $p {
            #[inline(always)]
            fn read(body: &[u8], at: usize, big: bool) -> Self {
                read_value::<$p>(body, at, big)
            }
        }
        impl<const N: usize> Value for [$p; N] {
            #[inline(always)]
            fn read(body: &[u8], at: usize, big: bool) -> Self {
                const SIZE: usize = <$p as Primitive>::SIZE;
                let bytes = &body[at..at + N * SIZE];
                core::array::from_fn(|i| read_value::<$p>(bytes, i * SIZE, big))
            }
        }
    )*};
}
value!(u8, i16, u16, i32, u32, f32);

/// A fixed-length array of structs inside a sample: `N` views of `V`.
pub struct StructArray<'a, V, const N: usize> {
    cursor: Cursor<'a>,
    element: PhantomData<V>,
}

impl<V, const N: usize> Clone for StructArray<'_, V, N> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<V, const N: usize> Copy for StructArray<'_, V, N> {}

impl<'a, V: StructView<'a>, const N: usize> StructArray<'a, V, N> {
    /// Number of elements.
    pub const LEN: usize = N;

    fn new(cursor: Cursor<'a>) -> Self {
        StructArray { cursor, element: PhantomData }
    }

    /// Number of elements (`N`).
    pub const fn len(&self) -> usize {
        N
    }

    /// Whether `N == 0`.
    pub const fn is_empty(&self) -> bool {
        N == 0
    }

    /// Element `i`, `None` past the end.
    #[inline]
    pub fn get(&self, i: usize) -> Option<V> {
        (i < N).then(|| self.element(i))
    }

    /// Every element in order.
    #[inline]
    pub fn iter(&self) -> impl DoubleEndedIterator<Item = V> + ExactSizeIterator + 'a {
        let this = *self;
        (0..N).map(move |i| this.element(i))
    }

    /// The owned elements.
    pub fn to_owned(&self) -> [V::Owned; N] {
        core::array::from_fn(|i| self.element(i).owned())
    }

    #[inline(always)]
    fn element(&self, i: usize) -> V {
        V::at(self.cursor.sub(i * V::LEAVES, V::LEAVES))
    }
}

impl<'a, V: StructView<'a>, const N: usize> core::fmt::Debug for StructArray<'a, V, N> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_list().entries(self.iter()).finish()
    }
}

/// A validated sample of `T`: the encoding, the header options and the view of its members
/// (reached through `Deref`: `view.tick()`, `view.motor_state().get(3)`).
pub struct MessageView<'a, T: Viewable> {
    encoding: Encoding,
    options: u16,
    root: T::View<'a>,
}

impl<T: Viewable> Clone for MessageView<'_, T> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<T: Viewable> Copy for MessageView<'_, T> {}

impl<T: Viewable> core::fmt::Debug for MessageView<'_, T> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("MessageView")
            .field("encoding", &self.encoding)
            .field("options", &self.options)
            .field("value", &self.root)
            .finish()
    }
}

impl<'a, T: Viewable> MessageView<'a, T> {
    /// Representation and byte order from the header.
    pub fn encoding(&self) -> Encoding {
        self.encoding
    }

    /// Option bytes of the header (big-endian), as received.
    pub fn options(&self) -> u16 {
        self.options
    }

    /// The view of the top-level struct (what `Deref` gives).
    pub fn fields(&self) -> T::View<'a> {
        self.root
    }

    /// The owned value: equal to what [`crate::decode`] returns for the same bytes.
    pub fn to_owned(&self) -> T {
        self.root.owned()
    }

    /// What [`crate::decode`] returns for the same bytes.
    pub fn to_decoded(&self) -> Decoded<T> {
        Decoded { value: self.to_owned(), encoding: self.encoding, options: self.options }
    }

    /// Whether the stored `crc` member (accessor `crc()`) is Unitree's CRC of the message. The
    /// CRC covers the C struct image, not the CDR bytes, so this builds the owned value.
    pub fn verify_crc(&self) -> bool
    where
        T: crate::crc::Checksummed,
    {
        crate::crc::verify(&self.to_owned())
    }
}

impl<'a, T: Viewable> core::ops::Deref for MessageView<'a, T> {
    type Target = T::View<'a>;
    fn deref(&self) -> &Self::Target {
        &self.root
    }
}

/// Validates `bytes` (header and payload) as a sample of `T` and returns a view of it. Fails
/// iff [`crate::decode`] fails, with the same error; costs a header parse and a length
/// comparison (plus one comparison per DHEADER in XCDR2).
#[inline]
pub fn view<T: Viewable>(bytes: &[u8]) -> Result<MessageView<'_, T>, DecodeError> {
    let (encoding, options, body) = split_sample(bytes)?;
    let layout = T::layout(encoding.representation);
    let big = encoding.endianness == Endianness::Big;
    layout.check(body, big)?;
    let cursor = Cursor { body, leaves: layout.leaf_offsets(), big };
    Ok(MessageView { encoding, options, root: T::View::at(cursor) })
}

/// Whether `a` and `b` list the same names in the same order (usable in constants).
#[doc(hidden)]
pub const fn same_names(a: &[&str], b: &[&str]) -> bool {
    if a.len() != b.len() {
        return false;
    }
    let mut i = 0;
    while i < a.len() {
        if !same_str(a[i], b[i]) {
            return false;
        }
        i += 1;
    }
    true
}

const fn same_str(a: &str, b: &str) -> bool {
    let (a, b) = (a.as_bytes(), b.as_bytes());
    if a.len() != b.len() {
        return false;
    }
    let mut i = 0;
    while i < a.len() {
        if a[i] != b[i] {
            return false;
        }
        i += 1;
    }
    true
}

/// Position of `name` in `names` (compile error through const evaluation if absent).
#[doc(hidden)]
pub const fn member_index(names: &[&str], name: &str) -> usize {
    let mut i = 0;
    while i < names.len() {
        if same_str(names[i], name) {
            return i;
        }
        i += 1;
    }
    panic!("no such member")
}

/// First leaf of each member, from each member's leaf count.
#[doc(hidden)]
pub const fn first_leaves<const N: usize>(counts: [usize; N]) -> [usize; N] {
    let mut first = [0; N];
    let mut i = 1;
    while i < N {
        first[i] = first[i - 1] + counts[i - 1];
        i += 1;
    }
    first
}

/// Sum of leaf counts.
#[doc(hidden)]
pub const fn total_leaves<const N: usize>(counts: [usize; N]) -> usize {
    let mut sum = 0;
    let mut i = 0;
    while i < N {
        sum += counts[i];
        i += 1;
    }
    sum
}

/// Declares the view of an IDL struct: `$view<'a>` with one accessor per member, named as the
/// member, of one of three kinds:
/// * `value(T)`: a primitive or a primitive array, returned by value;
/// * `view(V)`: a nested struct, returned as its view `V<'a>`;
/// * `views(V, N)`: an array of `N` structs, returned as a [`StructArray`] of `V<'a>`.
///
/// The member list must name the struct's members in declaration order (checked at compile time
/// against [`IdlStruct::MEMBERS`]), with their types (a struct literal built from the accessors
/// must compile). `to_owned` fills the owned struct in one reflection walk ([`fill`]).
macro_rules! struct_view {
    (
        $(#[$meta:meta])*
        $owned:path => $view:ident {
            $( $field:ident : $kind:ident ( $($spec:tt)* ) ),* $(,)?
        }
    ) => {
        $(#[$meta])*
        #[derive(Clone, Copy)]
        pub struct $view<'a> {
            cursor: $crate::view::Cursor<'a>,
        }

        impl<'a> $view<'a> {
            /// Leaf count of each member, in declaration order.
            const LEAF_COUNTS: [usize; <$owned as unitree_idl::IdlStruct>::MEMBERS.len()] =
                [$( struct_view!(@leaves $kind($($spec)*)) ),*];
            const FIRST_LEAF: [usize; <$owned as unitree_idl::IdlStruct>::MEMBERS.len()] =
                $crate::view::first_leaves(Self::LEAF_COUNTS);

            $(
                #[doc = concat!("Member `", stringify!($field), "`.")]
                #[inline]
                pub fn $field(&self) -> struct_view!(@type $kind($($spec)*)) {
                    const NAME: &str = unitree_idl::reflect::member_name(stringify!($field));
                    let leaf = const {
                        $view::<'static>::FIRST_LEAF[$crate::view::member_index(<$owned as unitree_idl::IdlStruct>::MEMBERS, NAME)]
                    };
                    struct_view!(@get self.cursor, leaf, $kind($($spec)*))
                }
            )*

            /// The owned struct (what decoding this instance gives).
            pub fn to_owned(&self) -> $owned {
                $crate::view::fill::<$owned>(self.cursor)
            }
        }

        // The member list names every member with its type: the owned struct can be built from
        // the accessors (a struct literal, so a missing member or a wrong type does not compile).
        const _: for<'a> fn(&$view<'a>) -> $owned = |v| {
            $owned { $( $field: struct_view!(@owned v.$field(), $kind($($spec)*)) ),* }
        };

        impl<'a> $crate::view::StructView<'a> for $view<'a> {
            type Owned = $owned;
            const LEAVES: usize = $crate::view::total_leaves(Self::LEAF_COUNTS);
            #[inline(always)]
            fn at(cursor: $crate::view::Cursor<'a>) -> Self {
                $view { cursor }
            }
            fn cursor(&self) -> $crate::view::Cursor<'a> {
                self.cursor
            }
            fn owned(&self) -> $owned {
                $view::to_owned(self)
            }
        }

        impl $crate::view::Viewable for $owned {
            type View<'a> = $view<'a>;
            fn layout_cache() -> &'static [std::sync::OnceLock<$crate::view::Layout>; 2] {
                static CACHE: [std::sync::OnceLock<$crate::view::Layout>; 2] = [std::sync::OnceLock::new(), std::sync::OnceLock::new()];
                &CACHE
            }
        }

        impl core::fmt::Debug for $view<'_> {
            fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
                core::fmt::Debug::fmt(&self.to_owned(), f)
            }
        }

        const _: () = assert!(
            $crate::view::same_names(
                <$owned as unitree_idl::IdlStruct>::MEMBERS,
                &[$( unitree_idl::reflect::member_name(stringify!($field)) ),*],
            ),
            concat!("view ", stringify!($view), ": members differ from the IDL declaration order"),
        );
        const _: () = assert!(
            !<$owned as unitree_idl::Field>::HAS_SEQUENCE && <$owned as unitree_idl::Field>::EVERY_BYTE_VALID,
            "views need a fixed layout in which every byte pattern decodes"
        );
    };

    (@leaves value($t:ty)) => { 1 };
    (@leaves view($v:ident)) => { <$v<'static> as $crate::view::StructView<'static>>::LEAVES };
    (@leaves views($v:ident, $n:expr)) => { $n * <$v<'static> as $crate::view::StructView<'static>>::LEAVES };

    (@type value($t:ty)) => { $t };
    (@type view($v:ident)) => { $v<'a> };
    (@type views($v:ident, $n:expr)) => { $crate::view::StructArray<'a, $v<'a>, $n> };

    (@get $c:expr, $leaf:expr, value($t:ty)) => { $c.value::<$t>($leaf) };
    (@get $c:expr, $leaf:expr, view($v:ident)) => {
        <$v<'a> as $crate::view::StructView<'a>>::at($c.sub($leaf, <$v<'a> as $crate::view::StructView<'a>>::LEAVES))
    };
    (@get $c:expr, $leaf:expr, views($v:ident, $n:expr)) => {
        $crate::view::StructArray::new($c.sub($leaf, $n * <$v<'a> as $crate::view::StructView<'a>>::LEAVES))
    };

    (@owned $e:expr, value($t:ty)) => { $e };
    (@owned $e:expr, view($v:ident)) => { $e.to_owned() };
    (@owned $e:expr, views($v:ident, $n:expr)) => { $e.to_owned() };
}
use struct_view;

/// Runs `$body` with the type alias `$T` bound to the Rust type of a
/// [`MessageType`](unitree_idl::MessageType) that has a view (`Some(body)`), or gives `None`
/// for the types with sequences (hg `HandCmd`, `HandState`). The one list of viewable types.
#[macro_export]
macro_rules! with_viewable_type {
    ($kind:expr, $T:ident => $body:expr) => {{
        use unitree_idl::{go, hg, MessageType as M};
        match $kind {
            M::HgLowCmd => {
                type $T = hg::LowCmd_;
                Some($body)
            }
            M::HgMotorCmd => {
                type $T = hg::MotorCmd_;
                Some($body)
            }
            M::HgLowState => {
                type $T = hg::LowState_;
                Some($body)
            }
            M::HgMotorState => {
                type $T = hg::MotorState_;
                Some($body)
            }
            M::HgImuState => {
                type $T = hg::IMUState_;
                Some($body)
            }
            M::HgPressSensorState => {
                type $T = hg::PressSensorState_;
                Some($body)
            }
            M::HgBmsCmd => {
                type $T = hg::BmsCmd_;
                Some($body)
            }
            M::HgBmsState => {
                type $T = hg::BmsState_;
                Some($body)
            }
            M::HgMainBoardState => {
                type $T = hg::MainBoardState_;
                Some($body)
            }
            M::GoLowCmd => {
                type $T = go::LowCmd_;
                Some($body)
            }
            M::GoMotorCmd => {
                type $T = go::MotorCmd_;
                Some($body)
            }
            M::GoLowState => {
                type $T = go::LowState_;
                Some($body)
            }
            M::GoMotorState => {
                type $T = go::MotorState_;
                Some($body)
            }
            M::GoImuState => {
                type $T = go::IMUState_;
                Some($body)
            }
            M::GoBmsCmd => {
                type $T = go::BmsCmd_;
                Some($body)
            }
            M::GoBmsState => {
                type $T = go::BmsState_;
                Some($body)
            }
            M::GoTimeSpec => {
                type $T = go::TimeSpec_;
                Some($body)
            }
            M::GoPathPoint => {
                type $T = go::PathPoint_;
                Some($body)
            }
            M::GoSportModeState => {
                type $T = go::SportModeState_;
                Some($body)
            }
            // Sequences, strings or booleans (the RPC types): no view.
            M::HgHandCmd
            | M::HgHandState
            | M::ApiRequest
            | M::ApiRequestHeader
            | M::ApiRequestIdentity
            | M::ApiRequestLease
            | M::ApiRequestPolicy
            | M::ApiResponse
            | M::ApiResponseHeader
            | M::ApiResponseStatus => None,
        }
    }};
}
