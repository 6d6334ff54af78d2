#!/bin/sh
# Seed the image corpus with valid images written by the core (the reference image and a few small
# ones from the unit tests are produced by `cargo run -p axcomp-core --example write_seed_images`).
set -e
cd "$(dirname "$0")"
mkdir -p corpus/image_parser
cargo run --quiet --manifest-path ../core/Cargo.toml --example write_seed_images -- corpus/image_parser
