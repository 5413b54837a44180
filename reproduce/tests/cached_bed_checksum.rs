//! A cached bed with one bit flipped is not simulated as the case's bed: its checksum says it
//! is corrupt, the console says so, and the bed is settled again into the bed it was.

#[path = "../../tests/common/mod.rs"]
mod common;

use common::case_toml;

/// A cached bed with one bit flipped (density 1.25 → 1.35, still valid JSON) is not used:
/// it is said to be corrupt and settled again, into the bed it was.
#[test]
fn a_flipped_bit_in_a_cached_bed_is_settled_again() {
    use slurry::settle::DryBedOptions;
    use slurry_reproduce::{bed, BedMethod, BedRecord};
    let tmp = tempfile::tempdir().unwrap();
    let cache = tmp.path().join("cache");
    let closed = case_toml([10, 10, 40], "precision = \"f32\"\nnu = 0.1", "", "steps = 1\noutput_every = 1");
    let text = format!(
        "gravity = [0.0, 0.0, -1.6e-4]\n{closed}\n[contacts]\n[[random_particles]]\nshape = \"sphere\"\n\
         diameter = 4.0\ndensity = 1.25\ncount = 8\nseed = 5\n"
    );
    let case = slurry::case::Case::parse(&text, "column.toml").unwrap();
    let method = BedMethod::Dry(DryBedOptions { min_steps: 100, ..DryBedOptions::default() });
    let (made, cached) = bed("column", &case, method, &cache, true, None).unwrap();
    assert!(!cached);
    let (again, cached) = bed("column", &case, method, &cache, true, None).unwrap();
    assert!(cached, "a whole entry is used");
    assert_eq!(again.bed.particles, made.bed.particles);

    let entry = std::fs::read_dir(cache.join("beds")).unwrap().next().unwrap().unwrap().path();
    let file = entry.join("bed.json");
    assert!(entry.join("bed.json.blake3").is_file(), "no checksum beside the bed");
    let mut bytes = std::fs::read(&file).unwrap();
    let at =
        String::from_utf8_lossy(&bytes).find("\"density\":1.25").expect("a density") + "\"density\":1.".len();
    bytes[at] ^= 1; // '2' -> '3'
    std::fs::write(&file, &bytes).unwrap();
    assert!(String::from_utf8_lossy(&bytes).contains("\"density\":1.35"));

    let (value, note) = slurry::io::checksum::load_cached_json::<BedRecord>(&file, "bed");
    assert!(value.is_none(), "the edited bed would be used");
    let note = note.expect("a line on the console");
    for n in ["corrupt", &file.display().to_string(), "made again"] {
        assert!(note.contains(n), "`{n}` missing from: {note}");
    }
    let (rebuilt, cached) = bed("column", &case, method, &cache, true, None).unwrap();
    assert!(!cached, "the edited bed was used");
    assert_eq!(rebuilt.bed.particles, made.bed.particles, "settled again into another bed");
    assert!(!String::from_utf8_lossy(&std::fs::read(&file).unwrap()).contains("1.35"));
}
