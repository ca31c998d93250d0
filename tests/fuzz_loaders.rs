//! A deterministic mutation fuzzer over every loader (OBJ, MTL, scene TOML, materials TOML,
//! ray files), seeded from the shipped rooms (issue 21, point 1). Each loader gets
//! `PROPSIM_FUZZ_CASES` mutated inputs (default 10,000), run in-process: a panic, or a case
//! over 10 s, fails the test with the seeds that reproduce it. A smaller set of mutated rooms
//! runs through every simulator as a subprocess, failing on a panic, a signal or 10 s.
//! Inputs that once failed are kept below as named regression cases.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use propsim::core::Ray;
use propsim::core::bench::{read_rays, write_rays};
use propsim::rf::{RfConfig, RfOptions};
use propsim::scene::obj::load_obj;
use propsim::scene::{self, LoadOptions, MaterialLibrary, World};

const ROOMS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/rooms");
/// Longest a single in-process case or simulator run may take.
const CASE_LIMIT: Duration = Duration::from_secs(10);
/// Mutated inputs per loader unless `PROPSIM_FUZZ_CASES` says otherwise.
const DEFAULT_CASES: u64 = 10_000;

/// Rooms whose files seed the fuzzer: (directory, OBJ, MTL). BRAS CR4 (7,800 lines) is left
/// out to keep the run short; its format is CR2's.
const SEED_ROOMS: [(&str, &str, &str); 6] = [
    ("shoebox", "shoebox.obj", "shoebox.mtl"),
    ("l_room", "l_room.obj", "l_room.mtl"),
    ("cornell_box", "cornell_box.obj", "cornell_box.mtl"),
    ("cornell_box_classic", "cornell_box_classic.obj", "cornell_box_classic.mtl"),
    ("street_canyon", "street_canyon.obj", "street_canyon.mtl"),
    ("bras_cr2", "CR2.obj", "CR2.mtl"),
];

/// A scratch directory in memory where there is one: rewriting a file on ext4 costs
/// milliseconds (the flush on close after truncation), which would dominate the run.
fn scratch() -> tempfile::TempDir {
    tempfile::tempdir_in("/dev/shm").or_else(|_| tempfile::tempdir()).unwrap()
}

fn cases() -> u64 {
    std::env::var("PROPSIM_FUZZ_CASES").ok().and_then(|v| v.parse().ok()).unwrap_or(DEFAULT_CASES)
}

/// SplitMix64: small, seedable, and the same everywhere.
struct Rng(u64);

impl Rng {
    fn new(seed: u64) -> Self {
        Rng(seed ^ 0x5eed_f00d_cafe_babe)
    }

    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    fn below(&mut self, n: usize) -> usize {
        if n == 0 { 0 } else { (self.next() % n as u64) as usize }
    }

    fn pick<'a, T>(&mut self, v: &'a [T]) -> &'a T {
        &v[self.below(v.len())]
    }
}

/// Values a number in the input is replaced with.
const NUMBERS: [&str; 22] = [
    "0",
    "-0",
    "-1",
    "1",
    "nan",
    "NaN",
    "inf",
    "-inf",
    "1e40",
    "-1e40",
    "1e-40",
    "3.4e38",
    "99999999999999999999",
    "-9223372036854775809",
    "4294967296",
    "18446744073709551615",
    "2147483647",
    "0.5",
    "1.5",
    "-0.5",
    "1e9",
    "",
];

/// Bytes inserted at random places.
const BYTES: [u8; 16] =
    [0, b'\n', b'#', b'/', b' ', b'-', b'.', b'"', b'[', b']', b'=', b',', 0xff, 0xc3, b'\t', b'\r'];

/// Byte ranges of the numbers in `text` (digits with a sign, point or exponent).
fn number_spans(text: &[u8]) -> Vec<(usize, usize)> {
    let mut spans = Vec::new();
    let mut i = 0;
    while i < text.len() {
        if text[i].is_ascii_digit() {
            let mut start = i;
            while start > 0 && matches!(text[start - 1], b'-' | b'+' | b'.') {
                start -= 1;
            }
            let mut end = i;
            while end < text.len()
                && (text[end].is_ascii_alphanumeric() || matches!(text[end], b'.' | b'-' | b'+'))
            {
                end += 1;
            }
            spans.push((start, end));
            i = end;
        } else {
            i += 1;
        }
    }
    spans
}

fn split_lines(text: &[u8]) -> Vec<Vec<u8>> {
    text.split(|&b| b == b'\n').map(<[u8]>::to_vec).collect()
}

/// One to four mutations of `text`; `others` are the lines of the other seed files (splices).
fn mutate(rng: &mut Rng, text: &[u8], others: &[Vec<u8>]) -> Vec<u8> {
    let mut out = text.to_vec();
    for _ in 0..1 + rng.below(4) {
        let mut lines = split_lines(&out);
        match rng.below(14) {
            // Numbers most often: they reach the checks behind the parsers.
            0..=4 => {
                let spans = number_spans(&out);
                if !spans.is_empty() {
                    let (a, b) = *rng.pick(&spans);
                    let n = rng.pick(&NUMBERS).as_bytes();
                    out.splice(a..b, n.iter().copied());
                }
                continue;
            }
            5 => {
                let i = rng.below(lines.len());
                lines.remove(i);
            }
            6 => {
                let i = rng.below(lines.len());
                let l = lines[i].clone();
                for _ in 0..1 + rng.below(3) {
                    lines.insert(i, l.clone());
                }
            }
            7 => {
                let (i, j) = (rng.below(lines.len()), rng.below(lines.len()));
                lines.swap(i, j);
            }
            8 if !out.is_empty() => {
                let i = rng.below(out.len());
                out[i] ^= 1 << rng.below(8);
                continue;
            }
            9 => {
                let i = rng.below(out.len() + 1);
                out.insert(i, *rng.pick(&BYTES));
                continue;
            }
            10 if !others.is_empty() => {
                let i = rng.below(lines.len() + 1);
                lines.insert(i, rng.pick(others).clone());
            }
            11 => {
                // A value fewer (or the keyword alone) on a random line.
                let i = rng.below(lines.len());
                let words: Vec<&[u8]> = lines[i].split(|&b| b == b' ').collect();
                if words.len() > 1 {
                    let keep = 1 + rng.below(words.len() - 1);
                    lines[i] = words[..keep].join(&b' ');
                }
            }
            12 if !others.is_empty() => {
                // A line's first word on another line's values (`Kd` on an `Ns` line, ...).
                let i = rng.below(lines.len());
                let other = rng.pick(others);
                let key = other.split(|&b| b == b' ').next().unwrap_or(b"");
                let rest: Vec<u8> = lines[i].iter().copied().skip_while(|&b| b != b' ').collect();
                lines[i] = [key, &rest].concat();
            }
            _ => {
                out.truncate(rng.below(out.len() + 1));
                continue;
            }
        }
        out = lines.join(&b'\n');
    }
    out
}

fn read(path: &Path) -> Vec<u8> {
    std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// A copy of every seed room in a temporary directory (so mutants sit beside the real files).
fn copy_rooms(dir: &Path) {
    for (room, _, _) in SEED_ROOMS.iter().chain(&[("showcase", "", "")]) {
        let to = dir.join(room);
        std::fs::create_dir_all(&to).unwrap();
        for e in std::fs::read_dir(Path::new(ROOMS).join(room)).unwrap().flatten() {
            std::fs::copy(e.path(), to.join(e.file_name())).unwrap();
        }
    }
}

/// Every line of every seed file of the given kind, for splicing.
fn all_lines(files: &[Vec<u8>]) -> Vec<Vec<u8>> {
    files.iter().flat_map(|f| split_lines(f)).filter(|l| !l.is_empty()).collect()
}

/// The outcome of one case: `Err` holds the panic message.
fn guarded(run: impl FnOnce()) -> Result<Duration, String> {
    let t = Instant::now();
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(run)).map_err(|p| {
        p.downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| p.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "panic".into())
    })?;
    Ok(t.elapsed())
}

/// Runs `case(seed)` for `n` seeds; fails naming every seed that panicked or overran.
fn fuzz(loader: &str, n: u64, mut case: impl FnMut(u64)) {
    let started = Instant::now();
    let mut failures = Vec::new();
    let mut slowest = (Duration::ZERO, 0);
    for seed in 0..n {
        match guarded(|| case(seed)) {
            Ok(t) if t > CASE_LIMIT => failures.push(format!("seed {seed}: took {t:?}")),
            Ok(t) => slowest = slowest.max((t, seed)),
            Err(e) => failures.push(format!("seed {seed}: panicked: {e}")),
        }
    }
    eprintln!(
        "fuzz {loader}: {n} cases in {:.1} s, slowest {:?} (seed {})",
        started.elapsed().as_secs_f64(),
        slowest.0,
        slowest.1
    );
    assert!(failures.is_empty(), "fuzz {loader}: {} failing cases: {failures:#?}", failures.len());
}

/// What a simulator checks after loading: the world, the acoustic points, the radio set-up.
fn use_scene(result: Result<scene::Scene, scene::SceneError>) {
    let Ok(s) = result else { return };
    let world = World::build(s);
    let _ = world.check_acoustic_points();
    let _ = propsim::acoustic::simulate::surface_acoustics(&world);
    let _ = RfConfig::from_scene(&world, &RfOptions::default());
    let _ = propsim::scene::report::report(&world, &[]);
}

/// The mutated OBJ of `seed`: (room, text).
fn obj_case(seed: u64, seeds: &[Vec<u8>], lines: &[Vec<u8>]) -> (usize, Vec<u8>) {
    let mut rng = Rng::new(seed);
    let room = rng.below(seeds.len());
    (room, mutate(&mut rng, &seeds[room], lines))
}

#[test]
fn fuzz_obj_loader() {
    let dir = scratch();
    copy_rooms(dir.path());
    let seeds: Vec<Vec<u8>> =
        SEED_ROOMS.iter().map(|(r, o, _)| read(&Path::new(ROOMS).join(r).join(o))).collect();
    let lines = all_lines(&seeds);
    fuzz("OBJ", cases(), |seed| {
        let (room, text) = obj_case(seed, &seeds, &lines);
        let (name, _, _) = SEED_ROOMS[room];
        let path = dir.path().join(name).join("fuzz.obj");
        std::fs::write(&path, &text).unwrap();
        let _ = load_obj(&path);
        // Every tenth case through the whole scene (materials, world, checks).
        if seed % 10 == 0 {
            let toml = std::fs::read_to_string(dir.path().join(name).join("scene.toml")).unwrap();
            let scene = dir.path().join(name).join("fuzz_scene.toml");
            std::fs::write(&scene, toml.replace(&format!("\"{}\"", SEED_ROOMS[room].1), "\"fuzz.obj\""))
                .unwrap();
            use_scene(scene::load(&scene, &LoadOptions::default()));
        }
    });
}

/// The mutated MTL of `seed`: (room, text).
fn mtl_case(seed: u64, seeds: &[Vec<u8>], lines: &[Vec<u8>]) -> (usize, Vec<u8>) {
    let mut rng = Rng::new(seed ^ 0x3171);
    let room = rng.below(seeds.len());
    (room, mutate(&mut rng, &seeds[room], lines))
}

fn mtl_seeds() -> Vec<Vec<u8>> {
    SEED_ROOMS.iter().map(|(r, _, m)| read(&Path::new(ROOMS).join(r).join(m))).collect()
}

#[test]
fn fuzz_mtl_loader() {
    let dir = scratch();
    copy_rooms(dir.path());
    let seeds = mtl_seeds();
    let lines = all_lines(&seeds);
    fuzz("MTL", cases(), |seed| {
        let (room, text) = mtl_case(seed, &seeds, &lines);
        let (name, obj, mtl) = SEED_ROOMS[room];
        std::fs::write(dir.path().join(name).join(mtl), &text).unwrap();
        let obj = dir.path().join(name).join(obj);
        let _ = load_obj(&obj);
        if seed % 10 == 0 {
            use_scene(scene::load(&dir.path().join(name).join("scene.toml"), &LoadOptions::default()));
        }
    });
}

fn scene_seeds() -> Vec<(String, Vec<u8>)> {
    SEED_ROOMS
        .iter()
        .map(|(r, _, _)| r.to_string())
        .chain(["showcase".to_string()])
        .map(|r| {
            let text = read(&Path::new(ROOMS).join(&r).join("scene.toml"));
            (r, text)
        })
        .collect()
}

#[test]
fn fuzz_scene_toml_loader() {
    let dir = scratch();
    copy_rooms(dir.path());
    let seeds = scene_seeds();
    let texts: Vec<Vec<u8>> = seeds.iter().map(|(_, t)| t.clone()).collect();
    let lines = all_lines(&texts);
    fuzz("scene TOML", cases(), |seed| {
        let mut rng = Rng::new(seed ^ 0x5ce4e);
        let room = rng.below(seeds.len());
        let text = mutate(&mut rng, &seeds[room].1, &lines);
        let path = dir.path().join(&seeds[room].0).join("fuzz.toml");
        std::fs::write(&path, &text).unwrap();
        use_scene(scene::load(&path, &LoadOptions::default()));
    });
}

/// Density grids (`[[media]]`, issue 26): the text format mutated from rooms/smoke's grid,
/// then queried (densities at points in and around the box, the majorant walk).
#[test]
fn fuzz_density_grid_loader() {
    use propsim::scene::density_grid::{DensityGrid, parse_raw, parse_text};
    let seed_text = read(&Path::new(ROOMS).join("smoke").join("smoke.txt"));
    let lines = all_lines(std::slice::from_ref(&seed_text));
    fuzz("density grid", cases(), |seed| {
        let mut rng = Rng::new(seed ^ 0x6d1d);
        let text = mutate(&mut rng, &seed_text, &lines);
        let _ = parse_raw(&text, [4, 4, (text.len() / 64).max(1)]);
        let Ok((dims, values)) = parse_text(&String::from_utf8_lossy(&text)) else { return };
        let Ok(grid) = DensityGrid::new(dims, values, glam::Vec3::ZERO, glam::Vec3::new(1.0, 2.0, 0.5))
        else {
            return;
        };
        for k in 0..8 {
            let o = glam::Vec3::new(k as f32 * 0.3 - 1.0, 1.0, 0.25);
            let ray = Ray::new(o, glam::Vec3::new(1.0, (k as f32 - 4.0) * 0.2, 0.1).normalize());
            let _ = grid.density(ray.at(k as f32 * 0.2));
            if let Some((t0, t1)) = grid.clip(&ray, 10.0) {
                grid.majorant_segments(&ray, t0, t1, |_, _, m| {
                    assert!(m.is_finite() && m >= 0.0);
                    false
                });
            }
        }
    });
}

#[test]
fn fuzz_materials_toml_loader() {
    let library = propsim::scene::materials::BUILTIN_LIBRARY_TOML.as_bytes().to_vec();
    let mut seeds = vec![library];
    // The scenes' own [materials] tables, as materials files.
    for (_, text) in scene_seeds() {
        let text = String::from_utf8(text).unwrap();
        let tables: Vec<&str> = text.split("\n[").filter(|t| t.starts_with("materials.")).collect();
        if !tables.is_empty() {
            seeds.push(format!("[{}", tables.join("\n[")).into_bytes());
        }
    }
    let lines = all_lines(&seeds);
    let path = Path::new("fuzz_materials.toml");
    let builtin = MaterialLibrary::builtin();
    fuzz("materials TOML", cases(), |seed| {
        let mut rng = Rng::new(seed ^ 0x3a7e);
        let i = if rng.below(4) == 0 { 0 } else { 1 + rng.below(seeds.len() - 1) };
        let text = mutate(&mut rng, &seeds[i], &lines);
        let mut lib = builtin.clone();
        if let Ok(text) = std::str::from_utf8(&text) {
            let _ = lib.add_toml(path, text);
        }
    });
}

/// Replaces whole little-endian f32 values of a ray file with special numbers, then mutates
/// bytes: flips, inserts, truncation, duplicated or dropped 24-byte records.
fn mutate_rays(rng: &mut Rng, bytes: &[u8]) -> Vec<u8> {
    let mut out = bytes.to_vec();
    let special = [
        0.0f32,
        -0.0,
        1.0,
        -1.0,
        f32::NAN,
        f32::INFINITY,
        f32::NEG_INFINITY,
        1e38,
        -1e38,
        1e-40,
        f32::MIN_POSITIVE,
    ];
    for _ in 0..1 + rng.below(4) {
        let n = out.len();
        match rng.below(6) {
            0 | 1 if n >= 4 => {
                let i = rng.below(n / 4) * 4;
                out[i..i + 4].copy_from_slice(&rng.pick(&special).to_le_bytes());
            }
            2 if n > 0 => {
                let i = rng.below(n);
                out[i] ^= 1 << rng.below(8);
            }
            3 => {
                let i = rng.below(n + 1);
                out.insert(i, rng.next() as u8);
            }
            4 => out.truncate(rng.below(n + 1)),
            _ if n >= 24 => {
                let i = rng.below(n / 24) * 24;
                let rec = out[i..i + 24].to_vec();
                if rng.below(2) == 0 {
                    out.splice(i..i, rec);
                } else {
                    out.drain(i..i + 24);
                }
            }
            _ => {}
        }
    }
    out
}

#[test]
fn fuzz_ray_file_loader() {
    let dir = scratch();
    let seed_file = dir.path().join("seed.bin");
    let rays: Vec<Ray> = (0..40)
        .map(|i| {
            let f = i as f32;
            Ray::new(glam::Vec3::new(f, -f, 1.5), glam::Vec3::new(1.0, 0.1 * f, -0.5).normalize())
        })
        .collect();
    write_rays(&seed_file, &rays).unwrap();
    let seed_bytes = read(&seed_file);
    let path = dir.path().join("fuzz.bin");
    fuzz("ray file", cases(), |seed| {
        let mut rng = Rng::new(seed ^ 0x4a75);
        std::fs::write(&path, mutate_rays(&mut rng, &seed_bytes)).unwrap();
        if let Ok(rays) = read_rays(&path) {
            assert!(
                rays.iter().all(|r| r.origin.is_finite() && r.dir.is_finite()),
                "non-finite ray accepted"
            );
        }
    });
}

/// How a subprocess ended.
enum Ending {
    Exit(i32),
    Signal,
    TimedOut,
}

/// Runs `propsim ARGS` with a time limit; stdout and stderr go to files in `dir`.
fn run_limited(dir: &Path, args: &[String]) -> (Ending, String) {
    let err_path = dir.join("stderr.txt");
    let err_file = std::fs::File::create(&err_path).unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_propsim"))
        .args(args)
        .arg("--threads")
        .arg("1")
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(err_file)
        .spawn()
        .expect("the binary runs");
    let started = Instant::now();
    let ending = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break match status.code() {
                Some(c) => Ending::Exit(c),
                None => Ending::Signal,
            };
        }
        if started.elapsed() > CASE_LIMIT {
            let _ = child.kill();
            let _ = child.wait();
            break Ending::TimedOut;
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    (ending, std::fs::read_to_string(&err_path).unwrap_or_default())
}

/// The simulators with small settings, on `scene`, writing under `out`.
fn commands(scene: &Path, out: &Path) -> Vec<Vec<String>> {
    let s = scene.display().to_string();
    let o = |name: &str| out.join(name).display().to_string();
    let words = |v: &[&str]| v.iter().map(|w| w.to_string()).collect::<Vec<String>>();
    vec![
        words(&["info", &s]),
        words(&[
            "render",
            &s,
            "--width",
            "24",
            "--height",
            "16",
            "--spp",
            "1",
            "--max-depth",
            "2",
            "-o",
            &o("r.png"),
        ]),
        words(&[
            "acoustic",
            &s,
            "--rays",
            "300",
            "--ism-order",
            "1",
            "--max-time-s",
            "0.3",
            "--out",
            &o("a"),
        ]),
        words(&[
            "rf",
            &s,
            "--rays",
            "2000",
            "--cell-m",
            "2",
            "--max-depth",
            "1",
            "--png-width",
            "300",
            "--extrapolate",
            "--out",
            &o("f"),
        ]),
    ]
}

/// Mutated rooms run through all four commands at the default size; more in proportion
/// with `PROPSIM_FUZZ_CASES`.
const SIMULATOR_CASES: u64 = 32;

fn simulator_cases() -> u64 {
    (SIMULATOR_CASES * cases() / DEFAULT_CASES).max(SIMULATOR_CASES)
}

/// One mutated room (the scene, its OBJ or its MTL) in `dir`, from `seed`; returns the scene.
fn mutated_room(dir: &Path, seed: u64) -> PathBuf {
    let mut rng = Rng::new(seed ^ 0x517);
    // The small rooms only, so that every run is quick.
    let (room, obj, mtl) = *rng.pick(&SEED_ROOMS[..2]);
    let src = Path::new(ROOMS).join(room);
    let to = dir.join(format!("{room}_{seed}"));
    std::fs::create_dir_all(&to).unwrap();
    for f in ["scene.toml", obj, mtl] {
        std::fs::copy(src.join(f), to.join(f)).unwrap();
    }
    let which = ["scene.toml", obj, mtl][rng.below(3)];
    let text = read(&src.join(which));
    let others = all_lines(&[read(&src.join("scene.toml")), read(&src.join(obj)), read(&src.join(mtl))]);
    std::fs::write(to.join(which), mutate(&mut rng, &text, &others)).unwrap();
    to.join("scene.toml")
}

#[test]
fn mutated_rooms_through_every_simulator() {
    let dir = scratch();
    let mut failures = Vec::new();
    let started = Instant::now();
    for seed in 0..simulator_cases() {
        let scene = mutated_room(dir.path(), seed);
        let out = dir.path().join(format!("out_{seed}"));
        for args in commands(&scene, &out) {
            let (ending, err) = run_limited(dir.path(), &args);
            let what = match ending {
                Ending::Exit(101) => "panicked",
                Ending::Exit(_) if err.contains("panicked") => "panicked",
                Ending::Exit(c) => {
                    if std::env::var("PROPSIM_FUZZ_VERBOSE").is_ok() {
                        eprintln!("seed {seed}: {} exit {c}: {}", args[0], err.trim());
                    }
                    continue;
                }
                Ending::Signal => "died by a signal",
                Ending::TimedOut => "ran over 10 s",
            };
            failures.push(format!("seed {seed}: {} {what}: {err}", args[0]));
        }
    }
    eprintln!(
        "fuzz simulators: {} mutated rooms x 4 commands in {:.1} s",
        simulator_cases(),
        started.elapsed().as_secs_f64()
    );
    assert!(failures.is_empty(), "{failures:#?}");
}

/// Whether an MTL text has a colour line with one or two numbers: what tobj 4.0.5 panicked on
/// (`parse_float3`'s unwrap) before the MTL was checked first.
fn has_short_colour(text: &[u8]) -> bool {
    String::from_utf8_lossy(text).lines().any(|l| {
        let w: Vec<&str> = l.split('#').next().unwrap_or("").split_whitespace().collect();
        matches!(w.first(), Some(&("Ka" | "Kd" | "Ks" | "Ke")))
            && (2..=3).contains(&w.len())
            && w[1..].iter().all(|v| v.parse::<f32>().is_ok())
    })
}

/// MTL seeds of `fuzz_mtl_loader` that panicked inside tobj before the MTL was checked first
/// (the first 12 of 10,000: the check's first complaint is the short colour line).
const MTL_REGRESSION_SEEDS: [u64; 12] = [10, 12, 22, 26, 47, 50, 87, 88, 89, 91, 97, 98];

#[test]
fn regression_mtl_short_colour_lines() {
    // The case of the issue, by hand.
    let dir = scratch();
    std::fs::write(dir.path().join("a.obj"), "mtllib a.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl m\nf 1 2 3\n")
        .unwrap();
    std::fs::write(dir.path().join("a.mtl"), "newmtl m\nKd 0.5\n").unwrap();
    let e = load_obj(&dir.path().join("a.obj")).unwrap_err().to_string();
    assert!(e.contains("a.mtl") && e.contains("line 2") && e.contains("Kd"), "{e}");
    // The fuzzer's seeds that hit it.
    copy_rooms(dir.path());
    let seeds = mtl_seeds();
    let lines = all_lines(&seeds);
    for seed in MTL_REGRESSION_SEEDS {
        let (room, text) = mtl_case(seed, &seeds, &lines);
        assert!(has_short_colour(&text), "seed {seed} no longer makes the input that failed");
        let (name, obj, mtl) = SEED_ROOMS[room];
        std::fs::write(dir.path().join(name).join(mtl), &text).unwrap();
        let e = guarded(|| {
            let e = load_obj(&dir.path().join(name).join(obj)).unwrap_err().to_string();
            assert!(e.contains(mtl) && e.contains("expected three numbers"), "seed {seed}: {e}");
        });
        assert!(e.is_ok(), "seed {seed}: {e:?}");
    }
}
