//! Occupancy-grid maps in the ROS `map_server` format as simulated worlds,
//! so the planner runs on a user's own map: the same input Nav2,
//! `ipa_coverage_planning` and most ROS coverage planners take.
//!
//! A map is a YAML file naming an image (PGM, binary `P5` or plain `P2`, or
//! PNG) and saying how to read it:
//!
//! ```yaml
//! image: lab.pgm          # relative to the YAML file
//! resolution: 0.05        # m per pixel
//! origin: [-10.0, -5.0, 0.0]   # (x, y, yaw) of the lower-left pixel
//! negate: 0
//! occupied_thresh: 0.65
//! free_thresh: 0.196
//! mode: trinary           # optional: trinary (default), scale or raw
//! ```
//!
//! A pixel is free floor when its occupancy is below `free_thresh`:
//! occupancy = (255 − v) / 255 (v / 255 with `negate`) in `trinary` and
//! `scale` mode, v / 100 in `raw` mode. Unknown and occupied pixels are both
//! non-free: the simulated robot sees a wall where the map stops knowing.
//! The origin's yaw is ignored (as most of ROS does); the world is built
//! axis-aligned in the map frame. A region of interest (`--region`) keeps
//! only the floor inside a box, to cover one room of a building's map.

use std::path::{Path, PathBuf};

use nalgebra::Point2;
use yaml_rust2::{Yaml, YamlLoader};

use crate::floorplan::{self, GreyImage, WALL_REFLECTIVITY};
use crate::geom::{pose, Pose};
use crate::world::{FreeRaster, World};

/// How pixel values map to occupancy (the `mode` key).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MapMode {
    /// Occupied / free / unknown by the two thresholds (the default).
    Trinary,
    /// Like trinary between the thresholds' meaning, values in between
    /// scaled; for free floor the same test applies.
    Scale,
    /// The value is the occupancy in percent (0 = free, 100 = occupied).
    Raw,
}

/// The contents of a map YAML file.
#[derive(Clone, Debug, PartialEq)]
pub struct MapMeta {
    /// The image, resolved against the YAML file's folder.
    pub image: PathBuf,
    /// Metres per pixel.
    pub resolution: f64,
    /// Position (m) of the lower-left pixel's lower-left corner.
    pub origin: Point2<f64>,
    /// Rotation of the map (rad), reported and ignored.
    pub yaw: f64,
    /// Whether white means occupied.
    pub(crate) negate: bool,
    /// Occupancy above which a pixel is occupied (0..1).
    pub(crate) occupied_thresh: f64,
    /// Occupancy below which a pixel is free (0..1).
    pub free_thresh: f64,
    /// How values are read.
    pub mode: MapMode,
}

/// Why a map could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum RosMapError {
    /// A file could not be read.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// The YAML does not parse.
    #[error("{path}: not valid YAML: {message}")]
    Yaml {
        /// The file.
        path: String,
        /// The parser's message.
        message: String,
    },
    /// A required key is missing.
    #[error("{path}: missing key `{key}` (a map_server map needs image, resolution and origin)")]
    MissingKey {
        /// The file.
        path: String,
        /// The key.
        key: &'static str,
    },
    /// A key has a value of the wrong kind or out of range.
    #[error("{path}: `{key}` {message}")]
    BadValue {
        /// The file.
        path: String,
        /// The key.
        key: &'static str,
        /// What is wrong.
        message: String,
    },
    /// The image is not a PGM or PNG this reader understands.
    #[error("map image {path}: {message}")]
    Image {
        /// The file.
        path: String,
        /// What is wrong.
        message: String,
    },
    /// A PNG image failed to decode.
    #[error(transparent)]
    Png(#[from] floorplan::FloorPlanError),
    /// The map, or the region of interest cut from it, holds no free floor.
    #[error("{path}: no free floor {place}")]
    NoFloor {
        /// The map file.
        path: String,
        /// Where: "in the map" or "inside the region (x0, y0)-(x1, y1) m".
        place: String,
    },
}

/// Parses the text of a map YAML file; `dir` is the folder relative image
/// paths are resolved against, `path` names the file in messages.
pub(crate) fn parse_meta(text: &str, dir: &Path, path: &str) -> Result<MapMeta, RosMapError> {
    let docs = YamlLoader::load_from_str(text).map_err(|e| RosMapError::Yaml {
        path: path.to_string(),
        message: e.to_string(),
    })?;
    let doc = docs.first().ok_or_else(|| RosMapError::Yaml {
        path: path.to_string(),
        message: "empty document".into(),
    })?;
    if !doc.is_hash() {
        return Err(RosMapError::Yaml {
            path: path.to_string(),
            message: "expected a mapping of keys (image, resolution, origin, ...)".into(),
        });
    }
    let bad = |key: &'static str, message: String| RosMapError::BadValue {
        path: path.to_string(),
        key,
        message,
    };
    let get = |key: &'static str| -> Result<&Yaml, RosMapError> {
        let v = &doc[key];
        if v.is_badvalue() {
            Err(RosMapError::MissingKey {
                path: path.to_string(),
                key,
            })
        } else {
            Ok(v)
        }
    };
    let number = |key: &'static str, v: &Yaml| -> Result<f64, RosMapError> {
        v.as_f64()
            .or_else(|| v.as_i64().map(|i| i as f64))
            .filter(|x| x.is_finite())
            .ok_or_else(|| bad(key, format!("must be a number, not {}", show(v))))
    };
    let image = get("image")?
        .as_str()
        .ok_or_else(|| bad("image", "must be a file name".into()))?;
    let image = dir.join(image);
    let resolution = number("resolution", get("resolution")?)?;
    if !(resolution > 0.0 && resolution <= 1.0) {
        return Err(bad(
            "resolution",
            format!("is {resolution} m per pixel; expected a value in (0, 1]"),
        ));
    }
    let origin = get("origin")?;
    let o = origin.as_vec().filter(|v| v.len() == 3).ok_or_else(|| {
        bad(
            "origin",
            format!("must be [x, y, yaw], not {}", show(origin)),
        )
    })?;
    let (ox, oy, yaw) = (
        number("origin", &o[0])?,
        number("origin", &o[1])?,
        number("origin", &o[2])?,
    );
    let optional = |key: &'static str, default: f64| -> Result<f64, RosMapError> {
        let v = &doc[key];
        if v.is_badvalue() {
            Ok(default)
        } else {
            number(key, v)
        }
    };
    let negate = match &doc["negate"] {
        Yaml::BadValue => false,
        Yaml::Boolean(b) => *b,
        Yaml::Integer(0) => false,
        Yaml::Integer(1) => true,
        v => return Err(bad("negate", format!("must be 0 or 1, not {}", show(v)))),
    };
    let occupied_thresh = optional("occupied_thresh", 0.65)?;
    let free_thresh = optional("free_thresh", 0.196)?;
    if !(0.0..=1.0).contains(&free_thresh)
        || !(0.0..=1.0).contains(&occupied_thresh)
        || free_thresh > occupied_thresh
    {
        return Err(bad(
            "free_thresh",
            format!(
                "is {free_thresh} with occupied_thresh {occupied_thresh}; expected 0 <= free_thresh <= occupied_thresh <= 1"
            ),
        ));
    }
    let mode = match &doc["mode"] {
        Yaml::BadValue => MapMode::Trinary,
        Yaml::String(s) if s == "trinary" => MapMode::Trinary,
        Yaml::String(s) if s == "scale" => MapMode::Scale,
        Yaml::String(s) if s == "raw" => MapMode::Raw,
        v => {
            return Err(bad(
                "mode",
                format!("must be trinary, scale or raw, not {}", show(v)),
            ))
        }
    };
    Ok(MapMeta {
        image,
        resolution,
        origin: Point2::new(ox, oy),
        yaw,
        negate,
        occupied_thresh,
        free_thresh,
        mode,
    })
}

/// A YAML value as a person would write it, for messages.
fn show(v: &Yaml) -> String {
    match v {
        Yaml::Real(s) | Yaml::String(s) => format!("`{s}`"),
        Yaml::Integer(i) => format!("`{i}`"),
        Yaml::Boolean(b) => format!("`{b}`"),
        Yaml::Array(a) => format!("a list of {}", a.len()),
        Yaml::Hash(_) => "a mapping".into(),
        _ => "nothing".into(),
    }
}

/// Decodes a PGM image (binary `P5` or plain `P2`, 8 or 16 bits; 16-bit
/// values are scaled to 8), row 0 at the top.
pub(crate) fn decode_pgm(bytes: &[u8]) -> Result<GreyImage, String> {
    let mut pos = 0;
    let mut token = |bytes: &[u8]| -> Result<String, String> {
        loop {
            while pos < bytes.len() && bytes[pos].is_ascii_whitespace() {
                pos += 1;
            }
            if pos < bytes.len() && bytes[pos] == b'#' {
                while pos < bytes.len() && bytes[pos] != b'\n' {
                    pos += 1;
                }
                continue;
            }
            break;
        }
        let start = pos;
        while pos < bytes.len() && !bytes[pos].is_ascii_whitespace() && bytes[pos] != b'#' {
            pos += 1;
        }
        if start == pos {
            return Err("header ends early".into());
        }
        Ok(String::from_utf8_lossy(&bytes[start..pos]).into_owned())
    };
    let magic = token(bytes)?;
    let binary = match magic.as_str() {
        "P5" => true,
        "P2" => false,
        m => return Err(format!("not a grey PGM (magic `{m}`, expected P5 or P2)")),
    };
    let mut dim = |what: &str| -> Result<usize, String> {
        let t = token(bytes)?;
        t.parse::<usize>()
            .ok()
            .filter(|&v| v > 0)
            .ok_or_else(|| format!("bad {what} `{t}` in the header"))
    };
    let width = dim("width")?;
    let height = dim("height")?;
    let maxval = dim("maximum value")?;
    if maxval > 65535 {
        return Err(format!("maximum value {maxval} is over 65535"));
    }
    let n = width
        .checked_mul(height)
        .filter(|&n| n <= 1 << 28)
        .ok_or_else(|| format!("{width} x {height} pixels is too large"))?;
    let scale = |v: usize| ((v.min(maxval) * 255 + maxval / 2) / maxval) as u8;
    let mut pixels = Vec::with_capacity(n);
    if binary {
        // Exactly one whitespace byte separates the header from the data.
        let data = bytes.get(pos + 1..).unwrap_or(&[]);
        let wide = maxval > 255;
        let need = if wide { 2 * n } else { n };
        if data.len() < need {
            return Err(format!(
                "truncated: {} of {need} data bytes for {width} x {height} pixels",
                data.len()
            ));
        }
        if wide {
            pixels.extend(
                data[..need]
                    .chunks_exact(2)
                    .map(|b| scale(usize::from(u16::from_be_bytes([b[0], b[1]])))),
            );
        } else {
            pixels.extend(data[..n].iter().map(|&b| scale(usize::from(b))));
        }
    } else {
        for k in 0..n {
            let t = token(bytes).map_err(|_| format!("truncated: {k} of {n} pixel values"))?;
            let v = t
                .parse::<usize>()
                .map_err(|_| format!("pixel {k}: `{t}` is not a number"))?;
            pixels.push(scale(v));
        }
    }
    Ok(GreyImage {
        width,
        height,
        pixels,
    })
}

/// Reads the map image: PNG by its signature, PGM otherwise.
pub(crate) fn load_image(path: &Path) -> Result<GreyImage, RosMapError> {
    let name = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|source| RosMapError::Io {
        path: name.clone(),
        source,
    })?;
    if bytes.starts_with(b"\x89PNG") {
        return Ok(floorplan::decode_grey(&bytes, &name)?);
    }
    decode_pgm(&bytes).map_err(|message| RosMapError::Image {
        path: name,
        message,
    })
}

/// Whether grey value `v` is free floor under `meta`'s thresholds.
pub fn is_free(meta: &MapMeta, v: u8) -> bool {
    let occupancy = match meta.mode {
        MapMode::Raw => f64::from(v) / 100.0,
        MapMode::Trinary | MapMode::Scale if meta.negate => f64::from(v) / 255.0,
        MapMode::Trinary | MapMode::Scale => (255.0 - f64::from(v)) / 255.0,
    };
    occupancy < meta.free_thresh
}

/// A box of the map frame (m): only floor inside it is kept.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Region {
    /// Lower-left corner (m).
    pub lo: Point2<f64>,
    /// Upper-right corner (m).
    pub hi: Point2<f64>,
}

impl std::str::FromStr for Region {
    type Err = String;

    /// Parses `X0,Y0,X1,Y1` (m, any two opposite corners).
    fn from_str(s: &str) -> Result<Self, String> {
        let v: Vec<f64> = s
            .split(',')
            .map(|t| t.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|_| format!("region `{s}` is not X0,Y0,X1,Y1 in metres"))?;
        if v.len() != 4 || v.iter().any(|x| !x.is_finite()) {
            return Err(format!("region `{s}` is not X0,Y0,X1,Y1 in metres"));
        }
        let (lo, hi) = (
            Point2::new(v[0].min(v[2]), v[1].min(v[3])),
            Point2::new(v[0].max(v[2]), v[1].max(v[3])),
        );
        if hi.x - lo.x <= 0.0 || hi.y - lo.y <= 0.0 {
            return Err(format!("region `{s}` has no area"));
        }
        Ok(Region { lo, hi })
    }
}

/// The map's free floor as a raster in the map frame (pixel (u, v) of the
/// image spans x = origin.x + u·res, y = origin.y + (H − 1 − v)·res), cut to
/// `region` when given, with a one-cell non-free border so the world is
/// closed.
pub fn raster(meta: &MapMeta, img: &GreyImage, region: Option<&Region>) -> FreeRaster {
    let res = meta.resolution;
    // Pixel columns / image rows inside the region (all of them without one).
    let (u0, u1, v0, v1) = match region {
        None => (0, img.width, 0, img.height),
        Some(r) => {
            let col = |x: f64| ((x - meta.origin.x) / res).floor().max(0.0) as usize;
            let row = |y: f64| ((y - meta.origin.y) / res).floor().max(0.0) as usize;
            let (c0, c1) = (col(r.lo.x).min(img.width), (col(r.hi.x) + 1).min(img.width));
            let (r0, r1) = (
                row(r.lo.y).min(img.height),
                (row(r.hi.y) + 1).min(img.height),
            );
            // Rows counted from the bottom; image rows from the top.
            (c0, c1, img.height - r1, img.height - r0)
        }
    };
    let (w, h) = (u1.saturating_sub(u0) + 2, v1.saturating_sub(v0) + 2);
    let mut free = vec![false; w * h];
    for v in v0..v1 {
        for u in u0..u1 {
            let c = Point2::new(
                meta.origin.x + (u as f64 + 0.5) * res,
                meta.origin.y + ((img.height - 1 - v) as f64 + 0.5) * res,
            );
            let inside = region
                .is_none_or(|r| c.x >= r.lo.x && c.x <= r.hi.x && c.y >= r.lo.y && c.y <= r.hi.y);
            if inside && is_free(meta, img.at(u, v)) {
                let row = v1 - v; // raster row 0 is the border below the lowest image row
                free[row * w + (u - u0) + 1] = true;
            }
        }
    }
    FreeRaster {
        origin: Point2::new(
            meta.origin.x + (u0 as f64 - 1.0) * res,
            meta.origin.y + ((img.height - v1) as f64 - 1.0) * res,
        ),
        resolution: res,
        width: w,
        height: h,
        free,
    }
}

/// Loads the map of YAML file `path` as a world: walls along every edge
/// between free and non-free pixels, cut to `region`, the robot starting at
/// `start` or else at the free point farthest from obstacles.
pub fn load_world(
    path: &Path,
    region: Option<&Region>,
    start: Option<Pose>,
) -> Result<World, RosMapError> {
    let name = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|source| RosMapError::Io {
        path: name.clone(),
        source,
    })?;
    let dir = path.parent().unwrap_or_else(|| Path::new("."));
    let meta = parse_meta(&text, dir, &name)?;
    if meta.yaw.abs() > 1e-9 {
        log::warn!(
            "{name}: origin yaw {:.3} rad ignored; the world is built in the map's pixel axes",
            meta.yaw
        );
    }
    let img = load_image(&meta.image)?;
    let raster = raster(&meta, &img, region);
    if !raster.free.iter().any(|&f| f) {
        let place = region.map_or_else(
            || "in the map (check negate and free_thresh)".to_string(),
            |r| {
                format!(
                    "inside the region ({}, {})-({}, {}) m",
                    r.lo.x, r.lo.y, r.hi.x, r.hi.y
                )
            },
        );
        return Err(RosMapError::NoFloor { path: name, place });
    }
    let start = start.unwrap_or_else(|| {
        let p = floorplan::farthest_from_obstacles(&raster);
        pose(p.x, p.y, 0.0)
    });
    let stem = path
        .file_stem()
        .map_or_else(|| name.clone(), |s| s.to_string_lossy().into_owned());
    Ok(World::from_raster(&stem, raster, WALL_REFLECTIVITY, start))
}

/// Parses a start pose `X,Y[,HEADING]` (m, m, rad).
pub fn parse_start(s: &str) -> Result<Pose, String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|t| t.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("start `{s}` is not X,Y or X,Y,HEADING"))?;
    match v.as_slice() {
        [x, y] if x.is_finite() && y.is_finite() => Ok(pose(*x, *y, 0.0)),
        [x, y, h] if x.is_finite() && y.is_finite() && h.is_finite() => Ok(pose(*x, *y, *h)),
        _ => Err(format!("start `{s}` is not X,Y or X,Y,HEADING")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn meta(text: &str) -> Result<MapMeta, RosMapError> {
        parse_meta(text, Path::new("/maps"), "test.yaml")
    }

    const GOOD: &str = "image: lab.pgm\nresolution: 0.05\norigin: [-1.0, 2, 0.0]\n\
                        negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n";

    #[test]
    fn a_map_server_yaml_parses_with_defaults_and_relative_image() {
        let m = meta(GOOD).unwrap();
        assert_eq!(m.image, PathBuf::from("/maps/lab.pgm"));
        assert_eq!(m.resolution, 0.05);
        assert_eq!(m.origin, Point2::new(-1.0, 2.0));
        assert!(!m.negate);
        assert_eq!(m.mode, MapMode::Trinary);
        let m =
            meta("image: a.png\nresolution: 1\norigin: [0, 0, 0]\nnegate: 1\nmode: raw\n").unwrap();
        assert!(m.negate);
        assert_eq!(m.mode, MapMode::Raw);
        assert_eq!(m.free_thresh, 0.196);
    }

    #[test]
    fn bad_map_yaml_names_the_key_and_what_is_wrong() {
        let cases = [
            ("resolution: 0.05\norigin: [0, 0, 0]\n", "missing key `image`"),
            ("image: a.pgm\norigin: [0, 0, 0]\n", "missing key `resolution`"),
            ("image: a.pgm\nresolution: -0.05\norigin: [0, 0, 0]\n", "`resolution` is -0.05"),
            ("image: a.pgm\nresolution: fine\norigin: [0, 0, 0]\n", "must be a number, not `fine`"),
            ("image: a.pgm\nresolution: 0.05\norigin: [0, 0]\n", "must be [x, y, yaw]"),
            ("image: a.pgm\nresolution: 0.05\norigin: [0, 0, 0]\nnegate: 2\n", "`negate` must be 0 or 1"),
            ("image: a.pgm\nresolution: 0.05\norigin: [0, 0, 0]\nmode: fancy\n", "must be trinary, scale or raw"),
            (
                "image: a.pgm\nresolution: 0.05\norigin: [0, 0, 0]\nfree_thresh: 0.9\noccupied_thresh: 0.5\n",
                "free_thresh <= occupied_thresh",
            ),
            ("image: [a\n", "not valid YAML"),
            ("- a\n- b\n", "expected a mapping"),
            ("", "empty document"),
        ];
        for (text, want) in cases {
            let e = meta(text).unwrap_err().to_string();
            assert!(e.contains(want), "{text:?}: {e}");
            assert!(e.starts_with("test.yaml"), "{e}");
        }
    }

    #[test]
    fn pgm_binary_plain_and_16_bit_decode_alike() {
        let p5 = b"P5\n# a comment\n3 2\n255\n\x00\xcd\xfe\xff\x10\x20";
        let img = decode_pgm(p5).unwrap();
        assert_eq!((img.width, img.height), (3, 2));
        assert_eq!(img.pixels, vec![0, 205, 254, 255, 16, 32]);
        let p2 = b"P2 3 2 255\n0 205 254\n255 16 # trailing comment\n 32\n";
        assert_eq!(decode_pgm(p2).unwrap().pixels, img.pixels);
        let wide = b"P5 2 1 65535\n\xff\xff\x00\x00";
        assert_eq!(decode_pgm(wide).unwrap().pixels, vec![255, 0]);
    }

    #[test]
    fn corrupt_pgm_is_an_error_not_a_panic() {
        let cases: [(&[u8], &str); 7] = [
            (b"", "header ends early"),
            (b"P6\n1 1\n255\n\x00\x00\x00", "not a grey PGM"),
            (b"P5\n3 2\n255\n\x00\x01", "truncated: 2 of 6"),
            (b"P5\n0 2\n255\n", "bad width"),
            (b"P5\n3 x\n255\n", "bad height"),
            (b"P2\n2 1\n255\n7", "truncated: 1 of 2"),
            (b"P5\n99999 99999\n255\n", "too large"),
        ];
        for (bytes, want) in cases {
            let e = decode_pgm(bytes).unwrap_err();
            assert!(
                e.contains(want),
                "{:?}: {e}",
                String::from_utf8_lossy(bytes)
            );
        }
    }

    #[test]
    fn thresholds_and_negate_decide_free_floor() {
        let m = meta(GOOD).unwrap();
        // gmapping: 254 free, 205 unknown, 0 occupied.
        assert!(is_free(&m, 254));
        assert!(!is_free(&m, 205));
        assert!(!is_free(&m, 0));
        let n = MapMeta {
            negate: true,
            ..m.clone()
        };
        assert!(is_free(&n, 0));
        assert!(!is_free(&n, 254));
        let r = MapMeta {
            mode: MapMode::Raw,
            ..m
        };
        assert!(is_free(&r, 0));
        assert!(!is_free(&r, 100));
        assert!(!is_free(&r, 255));
    }

    #[test]
    fn the_raster_keeps_map_coordinates_and_the_region_cuts_it() {
        // 4 x 3 image, all free but the top-left pixel; origin (10, 20), 0.5 m.
        let img = GreyImage {
            width: 4,
            height: 3,
            pixels: vec![0, 254, 254, 254, 254, 254, 254, 254, 254, 254, 254, 254],
        };
        let m = MapMeta {
            resolution: 0.5,
            origin: Point2::new(10.0, 20.0),
            ..meta(GOOD).unwrap()
        };
        let r = raster(&m, &img, None);
        assert_eq!((r.width, r.height), (6, 5));
        // The top-left pixel spans x 10..10.5, y 21..21.5.
        assert!(!r.is_free(&Point2::new(10.25, 21.25)));
        assert!(r.is_free(&Point2::new(10.75, 21.25)));
        assert!(r.is_free(&Point2::new(10.25, 20.25)));
        assert!(!r.is_free(&Point2::new(9.75, 20.25)), "border");
        assert!((r.free_area() - 11.0 * 0.25).abs() < 1e-9);
        // A region over the right half keeps 6 pixels.
        let reg: Region = "11.0,20.0,12.0,21.5".parse().unwrap();
        let c = raster(&m, &img, Some(&reg));
        assert!((c.free_area() - 6.0 * 0.25).abs() < 1e-9);
        assert!(c.is_free(&Point2::new(11.75, 21.25)));
        assert!(!c.is_free(&Point2::new(10.75, 21.25)));
        assert!("1,2,3".parse::<Region>().is_err());
        assert!("1,2,1,5".parse::<Region>().is_err());
        assert!(parse_start("1,2").is_ok() && parse_start("1,2,0.5").is_ok());
        assert!(parse_start("1").is_err() && parse_start("a,b").is_err());
    }
}
