//! Rooms cut from the benchmark floor plans of `../shared/maps/`
//! (ipa_coverage_planning test maps, 0.05 m per pixel) and turned into
//! simulated [`World`]s, the way the Bormann et al. (ICRA 2018) coverage
//! benchmark does it: the white area of `<map>_gt_segmentation.png` is
//! flood-filled (8-connected) into one region per room, each region is masked
//! with the free pixels of the furnished plan `<map>_furnitures.png`, and the
//! robot starts at the free pixel farthest from any obstacle.
//!
//! Rooms are numbered in the order their first pixel appears in a top-to-bottom,
//! left-to-right scan of the segmentation image, so `MAP:N` names one room
//! reproducibly.
//!
//! [`Furnishing::Bare`] takes the room's floor from the plan without furniture
//! `<map>.png` instead (walls only, same room numbers): what the furniture
//! costs a planner is then measured room by room.

use std::path::{Path, PathBuf};

use nalgebra::Point2;

use crate::geom::pose;
use crate::world::{FreeRaster, World};

/// Metres per pixel of the benchmark floor plans.
pub const PIXEL_SIZE: f64 = 0.05;
/// Grey value above which a pixel is free floor (the IPA convention).
pub(crate) const FREE_ABOVE: u8 = 250;
/// Reflectivity given to every wall of a floor-plan world.
pub(crate) const WALL_REFLECTIVITY: f64 = 0.5;

/// Why a floor plan or room could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum FloorPlanError {
    /// The image file could not be opened.
    #[error("cannot open floor plan {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// The file is not a PNG the decoder understands.
    #[error("floor plan {path} is not a readable PNG: {message}")]
    Decode {
        /// The file.
        path: String,
        /// The decoder's message.
        message: String,
    },
    /// The furnished plan and the segmentation differ in size.
    #[error("{map}: furnished plan is {a:?} px but the segmentation is {b:?} px")]
    SizeMismatch {
        /// Map base name.
        map: String,
        /// Furnished plan (width, height).
        a: (usize, usize),
        /// Segmentation (width, height).
        b: (usize, usize),
    },
    /// A room spec was not `MAP:N`.
    #[error("room spec `{0}` is not MAP:N (e.g. office_f:3)")]
    BadSpec(String),
    /// No floor plan of that name in the folder.
    #[error("no floor plan `{map}` in {dir}; the plans there: {known}")]
    UnknownMap {
        /// The name asked for.
        map: String,
        /// The folder looked in.
        dir: String,
        /// The plans the folder holds, comma separated.
        known: String,
    },
    /// The map has fewer rooms than asked for.
    #[error("{map} has {count} rooms; room {index} does not exist")]
    NoSuchRoom {
        /// Map base name.
        map: String,
        /// Rooms found.
        count: usize,
        /// Index asked for.
        index: usize,
    },
}

/// An 8-bit grey image, row 0 at the top (image convention).
#[derive(Clone, Debug)]
pub struct GreyImage {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Row-major grey values.
    pub pixels: Vec<u8>,
}

impl GreyImage {
    /// Grey value at column `x`, row `y` (0 outside).
    pub fn at(&self, x: usize, y: usize) -> u8 {
        if x < self.width && y < self.height {
            self.pixels[y * self.width + x]
        } else {
            0
        }
    }
}

/// Reads a PNG of any colour type and bit depth as 8-bit grey (luminance;
/// alpha ignored).
pub(crate) fn load_grey(path: &Path) -> Result<GreyImage, FloorPlanError> {
    let name = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|source| FloorPlanError::Io {
        path: name.clone(),
        source,
    })?;
    decode_grey(&bytes, &name)
}

/// Decodes PNG bytes as 8-bit grey (see [`load_grey`]); `name` names the
/// file in errors.
pub(crate) fn decode_grey(bytes: &[u8], name: &str) -> Result<GreyImage, FloorPlanError> {
    let name = name.to_string();
    let decode = |e: png::DecodingError| FloorPlanError::Decode {
        path: name.clone(),
        message: e.to_string(),
    };
    let mut decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    decoder.set_transformations(png::Transformations::normalize_to_color8());
    let mut reader = decoder.read_info().map_err(decode)?;
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| FloorPlanError::Decode {
            path: name.clone(),
            message: "image too large".into(),
        })?;
    let mut buf = vec![0u8; size];
    let info = reader.next_frame(&mut buf).map_err(decode)?;
    let (w, h) = (info.width as usize, info.height as usize);
    let channels = match info.color_type {
        png::ColorType::Grayscale => 1,
        png::ColorType::GrayscaleAlpha => 2,
        png::ColorType::Rgb => 3,
        png::ColorType::Rgba => 4,
        png::ColorType::Indexed => {
            return Err(FloorPlanError::Decode {
                path: name,
                message: "palette was not expanded".into(),
            })
        }
    };
    let stride = info.line_size;
    let mut pixels = Vec::with_capacity(w * h);
    for y in 0..h {
        let row = &buf[y * stride..y * stride + w * channels];
        for x in 0..w {
            let p = &row[x * channels..];
            let g = if channels >= 3 {
                let l = 0.299 * p[0] as f64 + 0.587 * p[1] as f64 + 0.114 * p[2] as f64;
                l.round().clamp(0.0, 255.0) as u8
            } else {
                p[0]
            };
            pixels.push(g);
        }
    }
    Ok(GreyImage {
        width: w,
        height: h,
        pixels,
    })
}

/// One room of a floor plan: its free pixels (furniture removed) inside its
/// bounding box.
#[derive(Clone, Debug)]
pub struct Room {
    /// Map base name, e.g. `office_f`.
    pub map: String,
    /// Room number within the map (see the module docs).
    pub index: usize,
    /// Left column of the bounding box in the image.
    pub x0: usize,
    /// Top row of the bounding box in the image.
    pub y0: usize,
    /// Bounding-box width (px).
    pub width: usize,
    /// Bounding-box height (px).
    pub height: usize,
    /// Row-major (image rows, top first) free pixels of the room.
    pub free: Vec<bool>,
    /// Height of the whole image (px), to flip rows into world y.
    pub(crate) image_height: usize,
    /// Whether the floor is the furnished plan's or the bare plan's.
    pub furnishing: Furnishing,
}

impl Room {
    /// Free floor area of the room (m²), without the furniture's footprint.
    pub fn free_area(&self) -> f64 {
        self.free.iter().filter(|&&f| f).count() as f64 * PIXEL_SIZE * PIXEL_SIZE
    }

    /// The room as a ground-truth raster in world coordinates (x right, y up;
    /// pixel (u, v) of the image spans x = u·0.05, y = (H − 1 − v)·0.05), with a
    /// one-pixel non-free border so the room is closed.
    pub fn raster(&self) -> FreeRaster {
        let (w, h) = (self.width + 2, self.height + 2);
        let mut free = vec![false; w * h];
        for v in 0..self.height {
            for u in 0..self.width {
                if self.free[v * self.width + u] {
                    // Raster row 0 is the lowest y = the bottom image row.
                    let row = self.height - v;
                    free[row * w + u + 1] = true;
                }
            }
        }
        let bottom_image_row = self.y0 + self.height; // one past the box
        FreeRaster {
            origin: Point2::new(
                (self.x0 as f64 - 1.0) * PIXEL_SIZE,
                (self.image_height as f64 - bottom_image_row as f64 - 1.0) * PIXEL_SIZE,
            ),
            resolution: PIXEL_SIZE,
            width: w,
            height: h,
            free,
        }
    }

    /// The room as a simulated world (walls along every free/non-free pixel
    /// edge), the robot starting at the free point farthest from obstacles,
    /// heading along +x.
    pub fn world(&self) -> World {
        let raster = self.raster();
        let start = farthest_from_obstacles(&raster);
        let bare = match self.furnishing {
            Furnishing::Furnished => "",
            Furnishing::Bare => " bare",
        };
        let name = format!("{}:{}{bare}", self.map, self.index);
        World::from_raster(
            &name,
            raster,
            WALL_REFLECTIVITY,
            pose(start.x, start.y, 0.0),
        )
    }
}

/// The free cell of `raster` farthest (Euclidean, brute force over obstacle
/// boundary cells) from any non-free cell; ties go to the first in row order.
pub(crate) fn farthest_from_obstacles(raster: &FreeRaster) -> Point2<f64> {
    let (w, h) = (raster.width, raster.height);
    let free = |x: i64, y: i64| raster.free_at(x, y);
    let mut boundary = Vec::new();
    for y in 0..h as i64 {
        for x in 0..w as i64 {
            if !free(x, y) && (free(x + 1, y) || free(x - 1, y) || free(x, y + 1) || free(x, y - 1))
            {
                boundary.push((x, y));
            }
        }
    }
    let mut dist = vec![f64::INFINITY; w * h];
    // Two-pass chamfer-free exact-ish transform: propagate the nearest boundary
    // cell (8SSEDT-like), enough to pick a start far from walls.
    let mut near: Vec<Option<(i64, i64)>> = vec![None; w * h];
    let mut queue = std::collections::VecDeque::new();
    for &(x, y) in &boundary {
        let i = y as usize * w + x as usize;
        near[i] = Some((x, y));
        dist[i] = 0.0;
        queue.push_back((x, y));
    }
    while let Some((x, y)) = queue.pop_front() {
        let src = near[y as usize * w + x as usize].unwrap_or((x, y));
        for (dx, dy) in crate::grid::NEIGHBOURS_8 {
            let (nx, ny) = (x + dx, y + dy);
            if !free(nx, ny) {
                continue;
            }
            let j = ny as usize * w + nx as usize;
            let d = (((nx - src.0).pow(2) + (ny - src.1).pow(2)) as f64).sqrt();
            if d + 1e-9 < dist[j] {
                dist[j] = d;
                near[j] = Some(src);
                queue.push_back((nx, ny));
            }
        }
    }
    let mut best = (f64::NEG_INFINITY, 0usize);
    for (i, &d) in dist.iter().enumerate() {
        if raster.free[i] && d.is_finite() && d > best.0 {
            best = (d, i);
        }
    }
    raster.centre_of(best.1 % w, best.1 / w)
}

/// The folder holding the benchmark PNGs inside the shared data folder.
pub const MAPS_DIR: &str = "maps/ipa_coverage_planning_test_maps";

/// Where `<map>_furnitures.png` and `<map>_gt_segmentation.png` live.
pub fn map_files(dir: &Path, map: &str) -> (PathBuf, PathBuf) {
    (
        dir.join(format!("{map}_furnitures.png")),
        dir.join(format!("{map}_gt_segmentation.png")),
    )
}

/// The base name of a floor plan given as the user may write it: `office_f`,
/// or one of its files (`office_f_furnitures`, `office_f.png`, ...).
pub(crate) fn map_base(name: &str) -> &str {
    let name = name.trim();
    let name = name.strip_suffix(".png").unwrap_or(name);
    ["_furnitures", "_gt_segmentation"]
        .iter()
        .find_map(|s| name.strip_suffix(s))
        .unwrap_or(name)
}

/// The base names of the floor plans in `dir` (those with a furnished plan),
/// sorted.
pub(crate) fn plan_names(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .filter_map(|e| {
            let n = e.file_name().to_string_lossy().into_owned();
            n.strip_suffix("_furnitures.png").map(str::to_string)
        })
        .collect();
    names.sort();
    names
}

/// Which floor of a benchmark room is simulated.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Furnishing {
    /// The furnished plan `<map>_furnitures.png` (the benchmark's rooms).
    #[default]
    Furnished,
    /// The plan without furniture, `<map>.png` (walls only); rooms keep the
    /// numbers they have furnished.
    Bare,
}

/// Cuts every room of floor plan `map` (base name, e.g. `office_f`) in `dir`.
/// Rooms with fewer than `min_pixels` free pixels are dropped.
pub fn rooms(dir: &Path, map: &str, min_pixels: usize) -> Result<Vec<Room>, FloorPlanError> {
    rooms_as(dir, map, min_pixels, Furnishing::Furnished)
}

/// [`rooms`], furnished or bare.
pub fn rooms_as(
    dir: &Path,
    map: &str,
    min_pixels: usize,
    furnishing: Furnishing,
) -> Result<Vec<Room>, FloorPlanError> {
    let map = map_base(map);
    let (furn_path, seg_path) = map_files(dir, map);
    if !furn_path.is_file() && dir.is_dir() {
        return Err(FloorPlanError::UnknownMap {
            map: map.to_string(),
            dir: dir.display().to_string(),
            known: plan_names(dir).join(", "),
        });
    }
    let furn = load_grey(&furn_path)?;
    let seg = load_grey(&seg_path)?;
    let floor = match furnishing {
        Furnishing::Furnished => None,
        Furnishing::Bare => Some(load_grey(&dir.join(format!("{map}.png")))?),
    };
    for other in [&seg].into_iter().chain(floor.as_ref()) {
        if (furn.width, furn.height) != (other.width, other.height) {
            return Err(FloorPlanError::SizeMismatch {
                map: map.to_string(),
                a: (furn.width, furn.height),
                b: (other.width, other.height),
            });
        }
    }
    Ok(cut_rooms(map, &furn, &seg, min_pixels, floor.as_ref()))
}

/// Cuts rooms from already loaded images (see [`rooms`]): numbered by the
/// furnished plan `furn`, their floor taken from `floor` where given (the
/// plan without furniture), else from `furn`.
pub(crate) fn cut_rooms(
    map: &str,
    furn: &GreyImage,
    seg: &GreyImage,
    min_pixels: usize,
    floor: Option<&GreyImage>,
) -> Vec<Room> {
    let furnishing = match floor {
        Some(_) => Furnishing::Bare,
        None => Furnishing::Furnished,
    };
    let floor = floor.unwrap_or(furn);
    let (w, h) = (seg.width, seg.height);
    let mut label = vec![u32::MAX; w * h];
    let mut out = Vec::new();
    let mut next = 0u32;
    let mut stack = Vec::new();
    for start in 0..w * h {
        if seg.pixels[start] <= FREE_ABOVE || label[start] != u32::MAX {
            continue;
        }
        let id = next;
        next += 1;
        label[start] = id;
        stack.push(start);
        let mut pixels = Vec::new();
        while let Some(i) = stack.pop() {
            pixels.push(i);
            for j in crate::grid::neighbours8_of(i, w, h) {
                if seg.pixels[j] > FREE_ABOVE && label[j] == u32::MAX {
                    label[j] = id;
                    stack.push(j);
                }
            }
        }
        let furnished = pixels
            .iter()
            .filter(|&&i| furn.pixels[i] > FREE_ABOVE)
            .count();
        if furnished < min_pixels.max(1) {
            continue;
        }
        let kept: Vec<usize> = pixels
            .into_iter()
            .filter(|&i| floor.pixels[i] > FREE_ABOVE)
            .collect();
        // A bare plan drawn with a wall over the whole room (never in the
        // benchmark's plans) leaves no floor: the room is left out.
        if kept.is_empty() {
            continue;
        }
        let (mut x0, mut y0, mut x1, mut y1) = (usize::MAX, usize::MAX, 0, 0);
        for &i in &kept {
            let (x, y) = (i % w, i / w);
            x0 = x0.min(x);
            y0 = y0.min(y);
            x1 = x1.max(x);
            y1 = y1.max(y);
        }
        let (bw, bh) = (x1 - x0 + 1, y1 - y0 + 1);
        let mut free = vec![false; bw * bh];
        for &i in &kept {
            free[(i / w - y0) * bw + (i % w - x0)] = true;
        }
        out.push(Room {
            map: map.to_string(),
            index: out.len(),
            x0,
            y0,
            width: bw,
            height: bh,
            free,
            image_height: h,
            furnishing,
        });
    }
    out
}

/// Parses a room spec `MAP:N` into (map, index).
pub(crate) fn parse_spec(spec: &str) -> Result<(String, usize), FloorPlanError> {
    let (m, n) = spec
        .rsplit_once(':')
        .ok_or_else(|| FloorPlanError::BadSpec(spec.to_string()))?;
    let n: usize = n
        .parse()
        .map_err(|_| FloorPlanError::BadSpec(spec.to_string()))?;
    if m.is_empty() || m.contains('/') {
        return Err(FloorPlanError::BadSpec(spec.to_string()));
    }
    Ok((m.to_string(), n))
}

/// Loads room `MAP:N` from `dir` (rooms smaller than 1 m² are not numbered).
pub fn load_room(dir: &Path, spec: &str) -> Result<Room, FloorPlanError> {
    load_room_as(dir, spec, Furnishing::Furnished)
}

/// [`load_room`], furnished or bare (same room numbers).
pub fn load_room_as(
    dir: &Path,
    spec: &str,
    furnishing: Furnishing,
) -> Result<Room, FloorPlanError> {
    let (map, index) = parse_spec(spec)?;
    let mut all = rooms_as(dir, &map, MIN_ROOM_PIXELS, furnishing)?;
    let count = all.len();
    if index >= count {
        return Err(FloorPlanError::NoSuchRoom { map, count, index });
    }
    Ok(all.swap_remove(index))
}

/// Rooms below this many free pixels (1 m²) are not numbered by [`load_room`].
pub const MIN_ROOM_PIXELS: usize = 400;

#[cfg(test)]
mod tests {
    use super::*;

    fn img(w: usize, h: usize, f: impl Fn(usize, usize) -> u8) -> GreyImage {
        let mut pixels = Vec::new();
        for y in 0..h {
            for x in 0..w {
                pixels.push(f(x, y));
            }
        }
        GreyImage {
            width: w,
            height: h,
            pixels,
        }
    }

    #[test]
    fn two_rooms_split_by_a_separator_and_masked_by_furniture() {
        // 20 x 10 image, border walls, a separator at x = 10, furniture in room 1.
        let seg = img(20, 10, |x, y| {
            if x == 0 || y == 0 || x == 19 || y == 9 || x == 10 {
                0
            } else {
                255
            }
        });
        let furn = img(20, 10, |x, y| {
            if x == 0 || y == 0 || x == 19 || y == 9 || (x == 14 && y == 4) {
                0
            } else {
                255
            }
        });
        let rooms = cut_rooms("t", &furn, &seg, 1, None);
        assert_eq!(rooms.len(), 2);
        assert_eq!(rooms[0].free.iter().filter(|&&f| f).count(), 9 * 8);
        assert_eq!(rooms[1].free.iter().filter(|&&f| f).count(), 8 * 8 - 1);
        // Bare: the furniture pixel is floor again, the numbers stay.
        let bare = img(20, 10, |x, y| {
            if x == 0 || y == 0 || x == 19 || y == 9 {
                0
            } else {
                255
            }
        });
        let bare_rooms = cut_rooms("t", &furn, &seg, 1, Some(&bare));
        assert_eq!(bare_rooms.len(), 2);
        assert_eq!(bare_rooms[1].free.iter().filter(|&&f| f).count(), 8 * 8);
        assert_eq!(
            (bare_rooms[1].x0, bare_rooms[1].y0),
            (rooms[1].x0, rooms[1].y0)
        );
        // A bare plan with no floor at all: no room, no panic.
        let walls = img(20, 10, |_, _| 0);
        assert!(cut_rooms("t", &furn, &seg, 1, Some(&walls)).is_empty());
        assert_eq!((rooms[0].x0, rooms[0].y0), (1, 1));
        let r = rooms[1].raster();
        // The furniture pixel (14, 4) maps to world x = 14·0.05, y = (10-1-4)·0.05.
        assert!(!r.is_free(&Point2::new(14.5 * PIXEL_SIZE, 5.5 * PIXEL_SIZE)));
        assert!(r.is_free(&Point2::new(13.5 * PIXEL_SIZE, 5.5 * PIXEL_SIZE)));
        assert!((r.free_area() - rooms[1].free_area()).abs() < 1e-9);
        let w = rooms[0].world();
        assert!(w.free.is_free(&w.start.translation.vector.into()));
    }

    #[test]
    fn bad_specs_are_refused() {
        for s in ["office_f", "office_f:x", ":3", "../x:1"] {
            assert!(
                matches!(parse_spec(s), Err(FloorPlanError::BadSpec(_))),
                "{s}"
            );
        }
        assert_eq!(
            parse_spec("lab_a_scan:4").unwrap(),
            ("lab_a_scan".into(), 4)
        );
    }

    #[test]
    fn missing_file_is_a_typed_error() {
        let e = rooms(Path::new("/nonexistent"), "nothing", 1).unwrap_err();
        assert!(e.to_string().contains("nothing_furnitures.png"), "{e}");
    }
}
