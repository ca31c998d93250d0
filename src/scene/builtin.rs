//! Scenes compiled into the binary, so the main commands run with no files at hand.
//! A built-in is named `builtin:NAME` wherever a scene path is accepted.

use std::path::{Path, PathBuf};

use super::error::SceneError;

/// A scene shipped inside the binary: its files, by name, and which one to load.
pub struct BuiltinScene {
    pub name: &'static str,
    pub description: &'static str,
    /// The file to load (a scene TOML or an OBJ), one of `files`.
    pub main: &'static str,
    pub files: &'static [(&'static str, &'static str)],
}

macro_rules! room_file {
    ($dir:literal, $file:literal) => {
        ($file, include_str!(concat!("../../rooms/", $dir, "/", $file)))
    };
}

/// Every built-in scene.
pub const BUILTIN_SCENES: &[BuiltinScene] = &[
    BuiltinScene {
        name: "showcase",
        description: "L-shaped room with glass and chrome spheres, a loudspeaker, two listeners and a 3.5 GHz access point",
        main: "showcase/scene.toml",
        files: &[
            ("showcase/scene.toml", include_str!("../../rooms/showcase/scene.toml")),
            ("l_room/l_room.obj", include_str!("../../rooms/l_room/l_room.obj")),
            ("l_room/l_room.mtl", include_str!("../../rooms/l_room/l_room.mtl")),
        ],
    },
    BuiltinScene {
        name: "shoebox",
        description: "10 x 8 x 3 m room, absorption 0.1, scattering 0.5: the reverberation test case",
        main: "scene.toml",
        files: &[
            room_file!("shoebox", "scene.toml"),
            room_file!("shoebox", "shoebox.obj"),
            room_file!("shoebox", "shoebox.mtl"),
        ],
    },
    BuiltinScene {
        name: "cornell_box",
        description: "the Cornell box, closed by a front wall, camera inside",
        main: "scene.toml",
        files: &[
            room_file!("cornell_box", "scene.toml"),
            room_file!("cornell_box", "cornell_box.obj"),
            room_file!("cornell_box", "cornell_box.mtl"),
        ],
    },
    BuiltinScene {
        name: "cornell_box_classic",
        description: "the classic open-front Cornell box with its camera: the render reference and benchmark",
        main: "scene.toml",
        files: &[
            room_file!("cornell_box_classic", "scene.toml"),
            room_file!("cornell_box_classic", "cornell_box_classic.obj"),
            room_file!("cornell_box_classic", "cornell_box_classic.mtl"),
        ],
    },
    BuiltinScene {
        name: "bras_cr2",
        description: "BRAS CR2 seminar room (CC BY-SA 4.0), 2 sources, 5 receivers",
        main: "scene.toml",
        files: &[
            room_file!("bras_cr2", "scene.toml"),
            room_file!("bras_cr2", "CR2.obj"),
            room_file!("bras_cr2", "CR2.mtl"),
            room_file!("bras_cr2", "ATTRIBUTION.md"),
        ],
    },
    BuiltinScene {
        name: "street_canyon",
        description: "a street between two rows of buildings with a 3.5 GHz rooftop transmitter: the radio benchmark",
        main: "scene.toml",
        files: &[
            room_file!("street_canyon", "scene.toml"),
            room_file!("street_canyon", "street_canyon.obj"),
            room_file!("street_canyon", "street_canyon.mtl"),
        ],
    },
];

/// Prefix that marks a built-in scene name in a scene argument.
pub const BUILTIN_PREFIX: &str = "builtin:";

/// The built-in called `name`.
pub fn find(name: &str) -> Option<&'static BuiltinScene> {
    BUILTIN_SCENES.iter().find(|s| s.name == name)
}

/// Writes a built-in's files to a fresh temporary directory (removed when the returned guard
/// drops) and returns the path of its main file.
pub fn materialize(name: &str) -> Result<(tempfile::TempDir, PathBuf), SceneError> {
    let scene = find(name).ok_or_else(|| {
        let known: Vec<&str> = BUILTIN_SCENES.iter().map(|s| s.name).collect();
        SceneError::invalid(
            format!("{BUILTIN_PREFIX}{name}"),
            format!("no such built-in scene (known: {})", known.join(", ")),
        )
    })?;
    let dir = tempfile::Builder::new()
        .prefix(&format!("propsim-{name}-"))
        .tempdir()
        .map_err(|e| SceneError::io(std::env::temp_dir(), &e))?;
    for (file, text) in scene.files {
        let p = dir.path().join(file);
        if let Some(parent) = p.parent() {
            std::fs::create_dir_all(parent).map_err(|e| SceneError::io(parent, &e))?;
        }
        std::fs::write(&p, text).map_err(|e| SceneError::io(&p, &e))?;
    }
    let main = dir.path().join(scene.main);
    Ok((dir, main))
}

/// The built-in name in `path` if it is `builtin:NAME`.
pub fn builtin_name(path: &Path) -> Option<&str> {
    path.to_str()?.strip_prefix(BUILTIN_PREFIX)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_builtin_loads() {
        for s in BUILTIN_SCENES {
            let scene = crate::scene::load(
                Path::new(&format!("{BUILTIN_PREFIX}{}", s.name)),
                &crate::scene::LoadOptions::default(),
            )
            .unwrap_or_else(|e| panic!("{}: {e}", s.name));
            assert!(scene.mesh.triangle_count() > 0);
            assert_eq!(scene.path, Path::new(&format!("{BUILTIN_PREFIX}{}", s.name)));
        }
        assert!(materialize("nope").is_err());
    }
}
