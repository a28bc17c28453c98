//! Builds the C++ layer of the DART engine (feature `dart`) against the system's DART.
//! (The engine work fills this in.)
pub fn build() {}
