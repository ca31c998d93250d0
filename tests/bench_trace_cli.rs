//! `propsim bench trace` with generated input: its three ray sets, their agreement between
//! closest hit and occlusion, and the files it writes for other tracers.

mod common;

use common::propsim;

/// `(rays, hits, occluded)` of the line of set `name`.
fn set_counts(stdout: &str, name: &str) -> (u64, u64, u64) {
    let line = stdout
        .lines()
        .find(|l| l.split_whitespace().next() == Some(name))
        .unwrap_or_else(|| panic!("no line for set {name} in:\n{stdout}"));
    let number_after = |key: &str| -> u64 {
        let words: Vec<&str> = line.split_whitespace().collect();
        let at = words.iter().position(|w| *w == key).unwrap_or_else(|| panic!("{key} in {line}"));
        words[at + 1].trim_end_matches(',').parse().unwrap()
    };
    let rays = line.split_whitespace().nth(1).unwrap().parse().unwrap();
    (rays, number_after("hits"), number_after("occluded"))
}

#[test]
fn generated_sets_agree_between_closest_hit_and_occlusion_and_are_written() {
    let dir = tempfile::tempdir().unwrap();
    let prefix = dir.path().join("bench");
    let (ok, out, err) = propsim(&[
        "bench",
        "trace",
        "--triangles",
        "20000",
        "--ray-count",
        "4096",
        "--repeat",
        "1",
        "--write-inputs",
        prefix.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    let mut fraction = std::collections::HashMap::new();
    for name in ["coherent", "incoherent", "hit-heavy"] {
        let (rays, hits, occluded) = set_counts(&out, name);
        assert_eq!(rays, 4096, "{name}");
        // Every generated ray is unbounded, so it is occluded exactly when it hits.
        assert_eq!(hits, occluded, "{name}");
        fraction.insert(name, hits as f64 / rays as f64);
        let file = dir.path().join(format!("bench_{name}.bin"));
        let bytes = std::fs::metadata(&file).unwrap_or_else(|e| panic!("{}: {e}", file.display())).len();
        assert_eq!(bytes, 4096 * 6 * 4, "{name}: six f32 a ray");
    }
    assert!(dir.path().join("bench.obj").exists());
    // Both camera sets look at the terrain's centre: the 35-degree view mostly sees sky past
    // the terrain's far edge, the 20-degree view mostly terrain.
    assert!(fraction["coherent"] < 0.5, "{fraction:?}");
    assert!(fraction["hit-heavy"] > 0.5, "{fraction:?}");
}
