//! Build script of `diff-physics`: each foreign engine that needs a C++ layer is built by its own module, and only
//! when its cargo feature is on, so that a build without those engines needs none of their libraries.
mod bullet;
mod dart;

fn main() {
    println!("cargo:rerun-if-changed=build");
    if std::env::var_os("CARGO_FEATURE_BULLET").is_some() {
        bullet::build();
    }
    if std::env::var_os("CARGO_FEATURE_DART").is_some() {
        dart::build();
    }
}
