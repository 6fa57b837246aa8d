//! Which world a simulation covers, shared by `sweepline sim` and
//! `sweepline coverage`: a world file, a room of the benchmark floor plans,
//! or a ROS `map_server` map (YAML + PGM/PNG) of the user's own.

use std::path::{Path, PathBuf};

use crate::sim::floorplan;
use crate::sim::ros_map::{self, Region};
use crate::sim::walker::{random_walkers, Walker};
use crate::sim::world::World;

/// World selection arguments.
#[derive(Debug, clap::Args)]
pub struct WorldArgs {
    /// World file (hw/worlds/*.world).
    #[arg(long, conflicts_with_all = ["room", "map"])]
    pub world: Option<PathBuf>,
    /// A room of a benchmark floor plan, MAP:N (e.g. office_f:3;
    /// `sweepline coverage --list-rooms MAP` lists them).
    #[arg(long, conflicts_with = "map")]
    pub room: Option<String>,
    /// With --room: the room without its furniture (the plan `MAP.png`,
    /// walls only; same room numbers), to tell what the furniture costs.
    #[arg(long, requires = "room")]
    pub bare: bool,
    /// Folder of the floor-plan PNGs (default: the shared data folder's maps).
    #[arg(long)]
    pub maps: Option<PathBuf>,
    /// A ROS map_server map: the YAML file naming a PGM or PNG occupancy
    /// image (free below free_thresh; unknown and occupied are walls).
    #[arg(long, value_name = "YAML")]
    pub map: Option<PathBuf>,
    /// With --map: keep only the floor inside this box of the map frame,
    /// X0,Y0,X1,Y1 in metres (one room of a building's map).
    #[arg(long, requires = "map", allow_hyphen_values = true)]
    pub region: Option<Region>,
    /// With --map: start pose `X,Y[,HEADING]` in the map frame (m, rad;
    /// default: the free point farthest from obstacles).
    #[arg(long, requires = "map", allow_hyphen_values = true, value_parser = ros_map::parse_start)]
    pub start: Option<crate::geom::Pose>,
    /// A person walking through the room: `RADIUS,SPEED,X0,Y0,X1,Y1[,X,Y...]`
    /// (m, m/s, way points in the world frame), out and back along the way
    /// points for the whole run; may be given more than once. The world
    /// file's `walker` lines add people too.
    #[arg(long, value_name = "SPEC", allow_hyphen_values = true)]
    pub walker: Vec<String>,
    /// People drawn at random for the room: each walks a straight clear
    /// line of 1.5 m or more, at 0.6-1.2 m/s, coming in at 0-300 s, for 2-6
    /// trips (see `--people-seed`); added to any `--walker` and `walker`
    /// lines.
    #[arg(long, default_value_t = 0, value_name = "N")]
    pub people: usize,
    /// Seed of the people `--people` draws (the same seed and room give the
    /// same people).
    #[arg(long, default_value_t = 1, value_name = "SEED")]
    pub people_seed: u64,
}

impl WorldArgs {
    /// Whether a world was named (--world, --room or --map).
    pub fn selected(&self) -> bool {
        self.world.is_some() || self.room.is_some() || self.map.is_some()
    }

    /// The folder of the benchmark floor plans.
    pub fn maps_dir(&self) -> PathBuf {
        self.maps
            .clone()
            .unwrap_or_else(|| crate::testdata::shared_dir().join(floorplan::MAPS_DIR))
    }

    /// Loads the selected world; `default` when none is selected (an error
    /// naming the options when there is no default either); with the
    /// `--walker` people added.
    pub fn load(
        &self,
        default: Option<&Path>,
    ) -> Result<World, Box<dyn std::error::Error + Send + Sync>> {
        let mut world = self.load_room(default)?;
        for spec in &self.walker {
            let w = Walker::parse(spec).map_err(|m| format!("--walker {spec}: {m}"))?;
            world
                .add_walker(w)
                .map_err(|m| format!("--walker {spec}: {m}"))?;
        }
        let drawn = random_walkers(&world, self.people, self.people_seed);
        if drawn.len() < self.people {
            log::warn!(
                "--people {}: only {} straight clear lines of 1.5 m or more found in {}",
                self.people,
                drawn.len(),
                world.name
            );
        }
        for w in drawn {
            log::info!(
                "--people: a person of {:.2} m walks ({:.2}, {:.2}) - ({:.2}, {:.2}) m at {:.2} m/s from {:.0} s, {} trips",
                w.radius,
                w.path[0].x,
                w.path[0].y,
                w.path[1].x,
                w.path[1].y,
                w.speed,
                w.after,
                w.trips.unwrap_or(0)
            );
            world.add_walker(w)?;
        }
        Ok(world)
    }

    fn load_room(
        &self,
        default: Option<&Path>,
    ) -> Result<World, Box<dyn std::error::Error + Send + Sync>> {
        // clap's `requires` is not enforced through the flattened group:
        // checked here, so a misplaced option is an error, not ignored.
        if self.bare && self.room.is_none() {
            return Err(
                "--bare needs --room MAP:N (it removes a floor-plan room's furniture)".into(),
            );
        }
        if self.map.is_none() && (self.region.is_some() || self.start.is_some()) {
            return Err("--region and --start need --map MAP.yaml".into());
        }
        if let Some(w) = &self.world {
            return Ok(World::load(w)?);
        }
        if let Some(spec) = &self.room {
            let furnishing = if self.bare {
                floorplan::Furnishing::Bare
            } else {
                floorplan::Furnishing::Furnished
            };
            return Ok(floorplan::load_room_as(&self.maps_dir(), spec, furnishing)?.world());
        }
        if let Some(m) = &self.map {
            return Ok(ros_map::load_world(m, self.region.as_ref(), self.start)?);
        }
        match default {
            Some(d) => Ok(World::load(d)?),
            None => Err(
                "give --world FILE, --room MAP:N or --map MAP.yaml (or --list-rooms MAP)".into(),
            ),
        }
    }
}

/// Simulated seconds a run may take: `given`, else an hour or 60 s per m² of
/// the world's free floor, whichever is longer (a building's map takes hours
/// at 0.226 m/s; the cap only stops a run that no longer makes progress).
pub fn time_cap(given: Option<f64>, world: &World) -> f64 {
    given.unwrap_or_else(|| (60.0 * world.free.free_area()).max(3600.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args() -> WorldArgs {
        WorldArgs {
            world: None,
            room: None,
            bare: false,
            maps: None,
            map: None,
            region: None,
            start: None,
            walker: Vec::new(),
            people: 0,
            people_seed: 1,
        }
    }

    #[test]
    fn options_without_the_one_they_qualify_are_errors() {
        let e = WorldArgs {
            bare: true,
            world: Some("hw/worlds/paper.world".into()),
            ..args()
        }
        .load(None)
        .unwrap_err();
        assert!(e.to_string().contains("--bare needs --room"), "{e}");
        let e = WorldArgs {
            start: Some(crate::geom::pose(1.0, 1.0, 0.0)),
            ..args()
        }
        .load(None)
        .unwrap_err();
        assert!(e.to_string().contains("need --map"), "{e}");
    }

    #[test]
    fn walkers_are_added_to_the_world_and_bad_ones_name_the_option() {
        let paper = concat!(env!("CARGO_MANIFEST_DIR"), "/hw/worlds/paper.world");
        let w = WorldArgs {
            world: Some(paper.into()),
            walker: vec!["0.2,1.0,0.5,3.6,6.0,3.6".into()],
            ..args()
        }
        .load(None)
        .unwrap();
        assert_eq!(w.walkers.len(), 1);
        for (spec, says) in [
            ("0.2,1.0,0.5,3.6", "--walker 0.2,1.0,0.5,3.6: walker takes"),
            ("0.2,1.0,0.5,3.6,9,3.6", "leaves the free floor"),
        ] {
            let e = WorldArgs {
                world: Some(paper.into()),
                walker: vec![spec.into()],
                ..args()
            }
            .load(None)
            .unwrap_err();
            assert!(e.to_string().contains(says), "{spec}: {e}");
        }
    }

    #[test]
    fn a_bare_room_without_its_plan_names_the_missing_file() {
        // The furnished plan and the segmentation only, from the shared maps.
        let shared = crate::require_shared!(floorplan::MAPS_DIR);
        let dir = std::env::temp_dir().join(format!("sweepline-bare-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (furn, seg) = floorplan::map_files(&shared, "office_f");
        for f in [furn, seg] {
            std::fs::copy(&f, dir.join(f.file_name().unwrap())).unwrap();
        }
        let a = WorldArgs {
            room: Some("office_f:0".into()),
            bare: true,
            maps: Some(dir.clone()),
            ..args()
        };
        let e = a.load(None).unwrap_err();
        let _ = std::fs::remove_dir_all(&dir);
        assert!(e.to_string().contains("office_f.png"), "{e}");
    }
}
