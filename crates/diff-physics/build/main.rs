//! Build script of `diff-physics`: each foreign engine that needs a C++ layer is built by its own module, and only
//! when its cargo feature is on, so that a build without those engines needs none of their libraries (nor `cc` and
//! `pkg-config`, optional build-dependencies enabled by the same features).
#[cfg(feature = "bullet")]
mod bullet;
#[cfg(feature = "dart")]
mod dart;

fn main() {
    println!("cargo:rerun-if-changed=build");
    #[cfg(feature = "bullet")]
    bullet::build();
    #[cfg(feature = "dart")]
    dart::build();
}
