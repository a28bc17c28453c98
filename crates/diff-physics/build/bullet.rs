//! Builds the C++ layer of the Bullet engine (feature `bullet`) against the system's double-precision Bullet:
//! Debian's `libbullet-dev` ships `bullet-float64.pc` (libraries `*-float64`, compiled with
//! `BT_USE_DOUBLE_PRECISION`), which pkg-config resolves to include path, define and link flags.
pub fn build() {
    println!("cargo:rerun-if-changed=cpp/bullet_glue.cpp");
    // Probe without emitting link flags yet: the glue's static library must come before the Bullet libraries it
    // uses on the link line (cc emits its own link line when it compiles).
    let mut probe = pkg_config::Config::new();
    probe.atleast_version("3.24").cargo_metadata(false);
    let lib = match probe.probe("bullet-float64") {
        Ok(lib) => lib,
        Err(e) => panic!(
            "feature `bullet` needs the double-precision Bullet 3.24+ (Debian: `apt-get install libbullet-dev`, which \
             provides bullet-float64.pc; see scripts/setup.sh): {e}"
        ),
    };
    let mut build = cc::Build::new();
    build.cpp(true).file("cpp/bullet_glue.cpp").flag_if_supported("-std=c++17").warnings(false);
    for path in &lib.include_paths {
        build.include(path);
    }
    for (name, value) in &lib.defines {
        build.define(name, value.as_deref());
    }
    build.compile("ulab_bullet_glue");
    for path in &lib.link_paths {
        println!("cargo:rustc-link-search=native={}", path.display());
    }
    for name in &lib.libs {
        println!("cargo:rustc-link-lib={name}");
    }
}
