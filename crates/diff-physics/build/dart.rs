//! Builds the C++ layer of the DART engine (feature `dart`, `cpp/dart_glue.cpp`) against the system's DART 6.12
//! (Debian `libdart-dev`, `libdart-utils-urdf-dev`, `libdart-collision-ode-dev`): include paths and DART's own
//! link flags from `pkg-config dart`, plus the ODE collision detector and the URDF loader, which `dart.pc` does
//! not list.
pub fn build() {
    println!("cargo:rerun-if-changed=cpp/dart_glue.cpp");
    let dart = match pkg_config::Config::new().atleast_version("6.12").probe("dart") {
        Ok(lib) => lib,
        Err(e) => panic!(
            "feature `dart` needs DART >= 6.12 with pkg-config metadata (Debian: apt-get install libdart-dev \
             libdart-utils-urdf-dev libdart-collision-ode-dev; scripts/setup.sh does it): {e}"
        ),
    };
    let mut build = cc::Build::new();
    build.cpp(true).file("cpp/dart_glue.cpp").includes(&dart.include_paths);
    // dart.pc asks for C++11, which DART 6.12's own headers (std::make_unique) no longer compile with; the
    // flag is dropped and C++17 used instead. DART's deprecation warnings are its own business.
    build.flag("-std=c++17").flag_if_supported("-Wno-deprecated-declarations").warnings(false);
    build.compile("ulab_dart_glue");
    for lib in ["dart-collision-ode", "ode", "dart-utils-urdf", "dart-utils", "stdc++"] {
        println!("cargo:rustc-link-lib={lib}");
    }
}
