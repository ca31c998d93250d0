//! OBJ + MTL loading through tobj: triangulated, one surface per `usemtl` name, with clear
//! errors for missing files, malformed lines and non-finite coordinates.

use std::cell::RefCell;
use std::collections::BTreeMap;
use std::io::BufReader;
use std::path::{Path, PathBuf};

use glam::Vec3;

use super::error::SceneError;
use crate::core::TriangleMesh;

/// What an MTL file says about one material (linear RGB as written).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MtlEntry {
    /// Diffuse colour (`Kd`).
    pub diffuse: Option<[f32; 3]>,
    /// Specular colour (`Ks`).
    pub specular: Option<[f32; 3]>,
    /// Specular exponent (`Ns`).
    pub shininess: Option<f32>,
    /// Index of refraction (`Ni`).
    pub optical_density: Option<f32>,
    /// Opacity (`d`).
    pub dissolve: Option<f32>,
    /// Emitted colour (`Ke`).
    pub emission: Option<[f32; 3]>,
    /// Illumination model (`illum`).
    pub illumination_model: Option<u8>,
}

/// A loaded OBJ.
#[derive(Debug, Default)]
pub struct ObjScene {
    /// The triangles.
    pub mesh: TriangleMesh,
    /// MTL data for the surfaces it defines, by `usemtl` name.
    pub mtl: BTreeMap<String, MtlEntry>,
    /// Triangles dropped because their area was zero (or not finite).
    pub degenerate_dropped: usize,
    /// Names of the file's objects and groups (`o`/`g` statements; "" before any).
    pub object_names: Vec<String>,
    /// Index into `object_names` of each triangle of `mesh`.
    pub object_of_triangle: Vec<u32>,
}

/// Surface name given to faces that come before any `usemtl`.
pub const DEFAULT_SURFACE: &str = "default";
/// Placeholder library that makes tobj keep every `usemtl` name, with or without an MTL.
const NAMES_LIBRARY: &str = "\u{1}propsim-usemtl-names";

/// The text with every `#` comment removed, line numbers unchanged. tobj reads a trailing
/// comment on a `v` line as extra vertex-colour values and fails; many exporters write them.
fn strip_comments(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for line in text.lines() {
        out.push_str(line.split('#').next().unwrap_or(""));
        out.push('\n');
    }
    out
}

/// First line (1-based) of `text` for which `bad` holds, to point the user at it.
fn find_line(text: &str, bad: impl Fn(&str) -> bool) -> Option<usize> {
    text.lines().position(|l| bad(l.trim())).map(|i| i + 1)
}

fn parses_floats(rest: &str, min: usize) -> bool {
    let vals: Vec<&str> = rest.split_whitespace().collect();
    vals.len() >= min && vals.iter().all(|v| v.parse::<f32>().is_ok())
}

/// Checks an MTL text (comments stripped) line by line before tobj sees it: tobj panics on a
/// colour with fewer than three numbers, and accepts any number. Errors read "line N: ...".
pub fn check_mtl(text: &str) -> Result<(), String> {
    for (i, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        let Some(key) = words.next() else { continue };
        let values: Vec<&str> = words.collect();
        let numbers = || -> Result<Vec<f32>, String> {
            values
                .iter()
                .map(|w| {
                    w.parse::<f32>()
                        .ok()
                        .filter(|v| v.is_finite())
                        .ok_or_else(|| format!("line {}: {key} value \"{w}\" is not a finite number", i + 1))
                })
                .collect()
        };
        let bad = |what: &str| Err(format!("line {}: {key} {}: {what}", i + 1, values.join(" ")));
        match key {
            "newmtl" if values.is_empty() => return Err(format!("line {}: newmtl needs a name", i + 1)),
            "Ka" | "Kd" | "Ks" | "Ke" | "Tf" => {
                let v = numbers()?;
                if v.len() != 3 {
                    return bad("expected three numbers (r g b)");
                }
                if key == "Ke" && v.iter().any(|x| *x < 0.0) {
                    return bad("emission must not be negative");
                }
                if key != "Ke" && v.iter().any(|x| !(0.0..=1.0).contains(x)) {
                    return bad("each component must be in [0, 1]");
                }
            }
            "Ns" | "Ni" | "d" | "Tr" => {
                let v = numbers()?;
                if v.len() != 1 {
                    return bad("expected one number");
                }
                if matches!(key, "d" | "Tr") && !(0.0..=1.0).contains(&v[0]) {
                    return bad("must be in [0, 1]");
                }
                if v[0] < 0.0 {
                    return bad("must be 0 or above");
                }
            }
            "illum" if !matches!(values[..], [v] if v.parse::<u8>().is_ok_and(|n| n <= 10)) => {
                return bad("expected an illumination model from 0 to 10");
            }
            _ => {}
        }
    }
    Ok(())
}

/// Runs tobj's parser on `run`, turning a panic inside it into an error: a backstop for
/// inputs the checks before it did not foresee. The default panic message is not printed.
fn without_panics<T>(run: impl FnOnce() -> T) -> Result<T, String> {
    install_quiet_hook();
    QUIET.with(|q| q.set(true));
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(run));
    QUIET.with(|q| q.set(false));
    result.map_err(|p| {
        let what = p
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| p.downcast_ref::<String>().cloned())
            .unwrap_or_default();
        format!("the OBJ/MTL parser failed on this file ({})", what.replace('\n', " "))
    })
}

thread_local! {
    /// Set while [`without_panics`] runs on this thread: its panics are not printed.
    static QUIET: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Wraps the panic hook once so that panics on a [`QUIET`] thread print nothing.
fn install_quiet_hook() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if !QUIET.with(|q| q.get()) {
                previous(info);
            }
        }));
    });
}

/// Why tobj rejected the file, with the offending line where it can be found.
fn describe_tobj_error(err: tobj::LoadError, text: &str, vertex_count: usize) -> String {
    use tobj::LoadError as E;
    let located = match err {
        E::PositionParseError => find_line(text, |l| {
            l.strip_prefix("v ").or(l.strip_prefix("v\t")).is_some_and(|r| !parses_floats(r, 3))
        })
        .map(|n| format!("line {n}: vertex position is not three numbers")),
        E::NormalParseError => {
            find_line(text, |l| l.strip_prefix("vn ").is_some_and(|r| !parses_floats(r, 3)))
                .map(|n| format!("line {n}: normal is not three numbers"))
        }
        E::TexcoordParseError => {
            find_line(text, |l| l.strip_prefix("vt ").is_some_and(|r| !parses_floats(r, 1)))
                .map(|n| format!("line {n}: texture coordinate is not a number"))
        }
        E::FaceParseError | E::InvalidPolygon | E::FaceVertexOutOfBounds => find_line(text, |l| {
            l.strip_prefix("f ").is_some_and(|r| {
                let idx: Vec<Option<i64>> =
                    r.split_whitespace().map(|w| w.split('/').next().and_then(|s| s.parse().ok())).collect();
                idx.len() < 3
                    || idx.iter().any(|i| match i {
                        None => true,
                        Some(i) => *i == 0 || i.unsigned_abs() as usize > vertex_count,
                    })
            })
        })
        .map(|n| format!("line {n}: face refers to a vertex that does not exist or is not a number")),
        E::ColorParseError => find_line(text, |l| {
            l.strip_prefix("v ").is_some_and(|r| {
                let n = r.split_whitespace().count();
                n != 3 && n != 4 && (n != 6 || !parses_floats(r, 6))
            })
        })
        .map(|n| {
            format!("line {n}: vertex has {} values (expected x y z, or x y z r g b)", "a wrong number of")
        }),
        _ => None,
    };
    located.unwrap_or_else(|| format!("malformed OBJ: {err}"))
}

/// Loads an OBJ file (and its MTL libraries) into a mesh with one surface per `usemtl` name.
pub fn load_obj(path: &Path) -> Result<ObjScene, SceneError> {
    let text = strip_comments(&std::fs::read_to_string(path).map_err(|e| SceneError::io(path, &e))?);
    let usemtl_names: Vec<String> = {
        let mut v: Vec<String> = Vec::new();
        for l in text.lines() {
            if let Some(name) = l.trim().strip_prefix("usemtl") {
                let name = name.trim().to_string();
                if !name.is_empty() && !v.contains(&name) {
                    v.push(name);
                }
            }
        }
        v
    };
    let vertex_count = text.lines().filter(|l| l.trim_start().starts_with("v ")).count();

    // Prepend a synthetic library so every usemtl name survives even without an MTL; real
    // libraries loaded later override these placeholders.
    let augmented = format!("mtllib {NAMES_LIBRARY}\n{text}");
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let missing_mtl: RefCell<Option<(PathBuf, String)>> = RefCell::new(None);
    let bad_mtl: RefCell<Option<(PathBuf, String)>> = RefCell::new(None);
    let options =
        tobj::LoadOptions { triangulate: true, single_index: false, ignore_points: true, ignore_lines: true };
    let loaded = without_panics(|| {
        tobj::load_obj_buf(&mut BufReader::new(augmented.as_bytes()), &options, |lib| {
            if lib.as_os_str() == NAMES_LIBRARY {
                let mut map = std::collections::HashMap::new();
                let mats = usemtl_names
                    .iter()
                    .enumerate()
                    .map(|(i, n)| {
                        map.insert(n.clone(), i);
                        tobj::Material { name: n.clone(), ..Default::default() }
                    })
                    .collect();
                return Ok((mats, map));
            }
            let full = dir.join(lib);
            match std::fs::read_to_string(&full) {
                Ok(mtl) => {
                    let mtl = strip_comments(&mtl);
                    if let Err(e) = check_mtl(&mtl) {
                        bad_mtl.borrow_mut().get_or_insert((full, e));
                        return Err(tobj::LoadError::MaterialParseError);
                    }
                    tobj::load_mtl_buf(&mut BufReader::new(mtl.as_bytes()))
                }
                Err(e) => {
                    missing_mtl.borrow_mut().get_or_insert((full, e.to_string()));
                    Err(tobj::LoadError::OpenFileFailed)
                }
            }
        })
    })
    .map_err(|e| SceneError::invalid(path, e))?;
    if let Some((mtl, reason)) = missing_mtl.into_inner() {
        return Err(SceneError::invalid(
            path,
            format!("material library {} cannot be opened ({reason})", mtl.display()),
        ));
    }
    if let Some((mtl, reason)) = bad_mtl.into_inner() {
        return Err(SceneError::invalid(mtl, reason));
    }
    let (models, materials) =
        loaded.map_err(|e| SceneError::invalid(path, describe_tobj_error(e, &text, vertex_count)))?;
    let materials = materials.map_err(|e| SceneError::invalid(path, format!("malformed MTL: {e}")))?;

    let mut out = ObjScene::default();
    for m in &materials {
        if m.name.is_empty() || usemtl_names.iter().all(|n| n != &m.name) {
            continue;
        }
        let real = m.diffuse.is_some()
            || m.specular.is_some()
            || m.shininess.is_some()
            || m.dissolve.is_some()
            || m.optical_density.is_some()
            || m.emissive.is_some();
        if !real {
            continue;
        }
        out.mtl.insert(
            m.name.clone(),
            MtlEntry {
                diffuse: m.diffuse,
                specular: m.specular,
                shininess: m.shininess,
                optical_density: m.optical_density,
                dissolve: m.dissolve,
                emission: m.emissive,
                illumination_model: m.illumination_model,
            },
        );
    }

    let mesh = &mut out.mesh;
    for model in &models {
        let m = &model.mesh;
        let surface_name = m
            .material_id
            .and_then(|i| materials.get(i))
            .map(|mat| mat.name.clone())
            .unwrap_or_else(|| DEFAULT_SURFACE.to_string());
        let surface = mesh.surface_id(&surface_name);
        let object = match out.object_names.iter().position(|n| n == &model.name) {
            Some(i) => i as u32,
            None => {
                out.object_names.push(model.name.clone());
                (out.object_names.len() - 1) as u32
            }
        };
        let base = mesh.positions.len() as u32;
        for (k, p) in m.positions.chunks_exact(3).enumerate() {
            let v = Vec3::new(p[0], p[1], p[2]);
            if !v.is_finite() {
                let line = nth_vertex_line(&text, k + base as usize);
                return Err(SceneError::invalid(
                    path,
                    format!("{}vertex {} has a non-finite coordinate {v}", line, k + 1 + base as usize),
                ));
            }
            mesh.positions.push(v);
        }
        for tri in m.indices.chunks_exact(3) {
            let t = [base + tri[0], base + tri[1], base + tri[2]];
            let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
            let area = 0.5 * (b - a).cross(c - a).length();
            if area.is_nan() || area <= 0.0 || t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
                out.degenerate_dropped += 1;
                continue;
            }
            mesh.triangles.push(t);
            mesh.surface_of_triangle.push(surface);
            out.object_of_triangle.push(object);
        }
    }
    Ok(out)
}

/// "line N: " of the `index`-th (0-based) vertex statement, or "" if it cannot be found.
/// tobj renumbers per model, so this is exact only for single-object files; good enough
/// to point at the first bad coordinate, which is what it is used for.
fn nth_vertex_line(text: &str, index: usize) -> String {
    text.lines()
        .enumerate()
        .filter(|(_, l)| l.trim_start().starts_with("v "))
        .find(|(_, l)| !parses_finite(l.trim_start()[2..].trim()))
        .or_else(|| text.lines().enumerate().filter(|(_, l)| l.trim_start().starts_with("v ")).nth(index))
        .map(|(n, _)| format!("line {}: ", n + 1))
        .unwrap_or_default()
}

fn parses_finite(rest: &str) -> bool {
    rest.split_whitespace().all(|v| v.parse::<f32>().is_ok_and(f32::is_finite))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mtl_lines_are_checked_with_their_line_numbers() {
        assert_eq!(
            check_mtl("newmtl m\nKd 0.5 0.5 0.5\nKe 4 4 4\nNs 10\nd 1\nillum 2\nmap_Kd x.png\n"),
            Ok(())
        );
        for (text, needle) in [
            ("newmtl m\nKd 0.5\n", "line 2: Kd 0.5: expected three numbers"),
            ("newmtl m\n\nKs 0.1 0.2\n", "line 3: Ks 0.1 0.2: expected three numbers"),
            ("Kd nan -5 1e40\n", "line 1: Kd value \"nan\" is not a finite number"),
            ("Kd 1e40 0 0\n", "not a finite number"),
            ("Kd 0.5 1.5 0.5\n", "[0, 1]"),
            ("Ke -1 0 0\n", "negative"),
            ("Ns\n", "expected one number"),
            ("Ni -1\n", "0 or above"),
            ("d 1.5\n", "[0, 1]"),
            ("illum 99\n", "illumination model"),
            ("newmtl\n", "needs a name"),
        ] {
            let e = check_mtl(text).unwrap_err();
            assert!(e.contains(needle), "{text:?}: {e}");
        }
    }

    #[test]
    fn a_panic_in_the_parser_becomes_an_error() {
        let r: Result<(), String> = without_panics(|| panic!("index out of bounds"));
        assert!(r.unwrap_err().contains("index out of bounds"));
        assert_eq!(without_panics(|| 7), Ok(7));
        // The thread is no longer quiet afterwards.
        assert!(!QUIET.with(|q| q.get()));
    }
}
