//! A deterministic fuzz test of the OpenVDB reader (`smokeshadow::medium::vdb`): truncations,
//! bit flips, and length and count fields overwritten with huge or negative values, applied to
//! the real files in `tests/data/volumes/`. Every mutant must read as `Ok` or as one `Err` line:
//! no panic (caught and reported with the mutant that caused it) and no abort (an allocation the
//! file asked for but cannot back would end the whole test process, which fails the run).

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::PathBuf;

use smokeshadow::medium::vdb::{self, Limits};

/// The test's own generator (SplitMix64): deterministic mutants, the same on every machine.
struct SplitMix(u64);

impl SplitMix {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

/// Reads everything a user's command would: the grid list, then every grid as a float grid.
/// Returns whether any read succeeded (for the count of mutants that still parse).
fn read_all(bytes: &[u8]) -> bool {
    // A small dense limit keeps a mutant whose box grew from allocating the default 128 MiB.
    let limits = Limits {
        max_dense_voxels: 1 << 22,
    };
    let Ok(grids) = vdb::list_grids(bytes) else {
        return false;
    };
    let mut any = false;
    for g in grids {
        if let Ok(grid) = vdb::read_float_grid(bytes, &g.name, &limits) {
            assert_eq!(
                grid.values.len() as u64,
                u64::from(grid.dims.x) * u64::from(grid.dims.y) * u64::from(grid.dims.z)
            );
            any = true;
        }
    }
    any
}

fn check(name: &str, what: &str, mutant: &[u8], panics: &mut Vec<String>) -> bool {
    match catch_unwind(AssertUnwindSafe(|| read_all(mutant))) {
        Ok(parsed) => parsed,
        Err(_) => {
            panics.push(format!("{name}: {what}"));
            false
        }
    }
}

#[test]
fn no_mutant_of_a_real_file_panics_or_aborts() {
    // Mutants per file: the smallest files get the most (each read of the 393 KB smoke frame
    // decompresses 90k voxels, ~30 ms in a debug build).
    let files = [
        ("openusd_smoke_000001_empty.vdb", 160, 1500),
        ("openusd_densityAndHeat.vdb", 120, 500),
        ("openusd_smoke_000003.vdb", 40, 120),
    ];
    let mut panics = Vec::new();
    let mut mutants = 0;
    let mut still_parse = 0;
    for (name, truncations, flips) in files {
        let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("tests/data/volumes")
            .join(name);
        let original = std::fs::read(&path).unwrap();
        assert!(read_all(&original), "{name} must read before it is mutated");
        let mut rng = SplitMix(0x5eed ^ original.len() as u64);
        // Truncations: every length through the header and the first grid's descriptor, then
        // lengths spread over the file.
        let header = original.len().min(400);
        let spread = (0..truncations).map(|i| i * original.len() / truncations);
        for length in (0..header).step_by(3).chain(spread) {
            still_parse += usize::from(check(
                name,
                &format!("truncated to {length} bytes"),
                &original[..length],
                &mut panics,
            ));
            mutants += 1;
        }
        for _ in 0..flips {
            let mut mutant = original.clone();
            let at = rng.below(mutant.len());
            let what = match rng.below(3) {
                0 => {
                    let bit = rng.below(8);
                    mutant[at] ^= 1 << bit;
                    format!("bit {bit} of byte {at} flipped")
                }
                1 => {
                    let value: u64 = [
                        u64::MAX,
                        0x7fff_ffff,
                        0xffff_ffff,
                        0x8000_0000,
                        (-1i64) as u64,
                        1 << 40,
                    ][rng.below(6)];
                    let width = if rng.below(2) == 0 { 4 } else { 8 };
                    let end = (at + width).min(mutant.len());
                    mutant[at..end].copy_from_slice(&value.to_le_bytes()[..end - at]);
                    format!("{width} bytes at {at} set to {value:#x}")
                }
                _ => {
                    let byte = rng.next() as u8;
                    mutant[at] = byte;
                    format!("byte {at} set to {byte:#x}")
                }
            };
            still_parse += usize::from(check(name, &what, &mutant, &mut panics));
            mutants += 1;
        }
    }
    assert!(
        panics.is_empty(),
        "{} of {mutants} mutants panicked, e.g.:\n{}",
        panics.len(),
        panics[..panics.len().min(10)].join("\n")
    );
    // The mutants reach past the header: many still parse (a flipped value bit), many do not.
    assert!(
        still_parse > mutants / 10 && still_parse < mutants,
        "{still_parse} of {mutants}"
    );
}
