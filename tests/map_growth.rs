//! Map size grows with the length of surface seen, not with the number of
//! scans: driving the same loop through the paper's room 10 times (σ = 10 mm
//! range noise, registered poses off by σ = 1 cm / 0.3°), the point count after
//! the 10th pass stays within 1.1× the count after the first.

mod map_support;

use map_support::*;
use sweepline::map::{Map, MapParams, ScanQuality};
use sweepline::sim::world::World;

#[test]
fn revisiting_a_room_ten_times_barely_grows_the_map() {
    let (_, text) = &worlds()[0];
    let world = World::parse(text).unwrap();
    let mut loop_path = world_paths()[0].clone();
    loop_path.push(loop_path[0]);
    let poses = path(&loop_path, 0.1);
    let mut noise = rng(5);
    let mut map = Map::new(MapParams::default(), poses[0]).unwrap();
    let mut after_pass = Vec::new();
    let mut curve = String::from("scan,points,segments\n");
    let mut scans = 0;
    for _pass in 0..10 {
        for truth in &poses {
            let s = urg_scan(&world, truth, 0.01, &mut noise);
            let registered = jitter(truth, 0.01, 0.3f64.to_radians(), &mut noise);
            let r = map.update(&s, &registered, ScanQuality::Good).unwrap();
            scans += 1;
            curve.push_str(&format!(
                "{scans},{},{}\n",
                r.points_total, r.segments_total
            ));
        }
        after_pass.push(map.points().len());
    }
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("target/map-pictures");
    let _ = std::fs::create_dir_all(&dir);
    let _ = std::fs::write(dir.join("growth_paper_10_passes.csv"), &curve);
    map.publish();
    let snap = map.snapshot();
    let walls: Vec<_> = world.walls.iter().map(|w| w.seg).collect();
    save_svg(
        "growth_paper_10_passes.svg",
        &sweepline::map::svg::render(&snap, &walls),
    );
    let ratio = after_pass[9] as f64 / after_pass[0] as f64;
    eprintln!(
        "points after each pass: {after_pass:?}; ratio 10th/1st = {ratio:.3}; {} scans/pass",
        poses.len()
    );
    assert!(after_pass[0] > 500, "first pass stored too few points");
    assert!(ratio <= 1.1, "map grew {ratio:.3}x over 10 passes");
}
