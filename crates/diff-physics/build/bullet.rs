//! Builds the C++ layer of the Bullet engine (feature `bullet`) against the system's double-precision Bullet.
//! (The engine work fills this in.)
pub fn build() {}
