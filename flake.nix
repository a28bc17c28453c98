# Nix packaging of ulab (crane). UNTESTED: Nix cannot run on the machines this project is
# developed and tested on; the supported set-up is scripts/setup.sh (see README).
{
  description = "ulab: Rust toolkit for Unitree robots (SDK2 low-level DDS, multi-engine physics)";

  inputs = {
    nixpkgs.url = "github:NixOS/nixpkgs/nixos-unstable";
    crane.url = "github:ipetkov/crane";
    flake-utils.url = "github:numtide/flake-utils";
  };

  outputs = { self, nixpkgs, crane, flake-utils, ... }:
    flake-utils.lib.eachDefaultSystem (system:
      let
        pkgs = import nixpkgs { inherit system; };
        craneLib = crane.mkLib pkgs;
        # Keep the corpus, robot files and snapshots: tests and include_str! read them.
        src = pkgs.lib.cleanSourceWith {
          src = ./.;
          filter = path: type:
            (craneLib.filterCargoSources path type)
            || (builtins.match ".*(corpus|robots|snapshots)/.*" path != null);
        };
        # clang: physx-sys's build script compiles the vendored PhysX SDK with `clang++` (unless CXX is set).
        nativeBuildInputs = [ pkgs.cmake pkgs.pkg-config pkgs.rustPlatform.bindgenHook pkgs.clang ];
        buildInputs = [ pkgs.mujoco pkgs.cyclonedds ];
        commonArgs = {
          inherit src nativeBuildInputs buildInputs;
          strictDeps = true;
          # mujoco-rs links the system MuJoCo library dynamically.
          MUJOCO_DYNAMIC_LINK_DIR = "${pkgs.mujoco}/lib";
        };
        cargoArtifacts = craneLib.buildDepsOnly commonArgs;
        ulab = craneLib.buildPackage (commonArgs // {
          inherit cargoArtifacts;
          cargoExtraArgs = "-p ulab";
          doCheck = false; # the test suite needs the Python oracles from PyPI (scripts/setup.sh)
        });
        # Fuzz targets: their own workspace under fuzz/, instrumented like scripts/fuzz.sh does.
        fuzzTargets = craneLib.buildPackage (commonArgs // {
          pname = "ulab-fuzz";
          cargoToml = ./fuzz/Cargo.toml;
          cargoLock = ./fuzz/Cargo.lock;
          postUnpack = "cd $sourceRoot/fuzz && sourceRoot=.";
          RUSTFLAGS = "--cfg fuzzing -Cpasses=sancov-module -Cllvm-args=-sanitizer-coverage-level=4 -Cllvm-args=-sanitizer-coverage-inline-8bit-counters -Cllvm-args=-sanitizer-coverage-pc-table -Cllvm-args=-sanitizer-coverage-trace-compares";
          doCheck = false;
        });
      in
      {
        packages = {
          default = ulab;
          inherit ulab;
          fuzz = fuzzTargets;
        };
        apps.default = flake-utils.lib.mkApp { drv = ulab; };
        devShells.default = craneLib.devShell {
          inputsFrom = [ ulab ];
          packages = [
            pkgs.cmake pkgs.llvmPackages.libclang pkgs.mujoco pkgs.cyclonedds
            pkgs.cargo-fuzz pkgs.python311 pkgs.wireshark-cli
          ];
          MUJOCO_DYNAMIC_LINK_DIR = "${pkgs.mujoco}/lib";
          LIBCLANG_PATH = "${pkgs.llvmPackages.libclang.lib}/lib";
        };
      });
}
