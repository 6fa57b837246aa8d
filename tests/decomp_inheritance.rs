//! Cell inheritance on the paper's workspace: the robot explores step by
//! step; ids persist, cells become final, pictures of the evolution.

mod decomp_support;

use decomp_support::*;
use sweepline::decomp::{svg, CellStatus, DecompParams, Decomposer};
use sweepline::geom::pose;

fn out_dir() -> std::path::PathBuf {
    let d = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("decomp");
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn paper_workspace_evolution() {
    let world = paper_world();
    let mut grid = grid_for(&world, 0.05);
    let mut dec = Decomposer::new(&DecompParams::default(), 0.17).unwrap();
    let path = [
        (0.5, 0.5, 0.0),
        (1.2, 1.2, 0.5),
        (2.5, 1.2, 0.0),
        (3.0, 0.8, 0.0),
        (4.8, 1.0, 0.5),
        (5.4, 2.2, 1.6),
        (4.8, 3.3, 3.1),
        (3.0, 3.4, 3.1),
        (2.0, 2.5, 3.5),
        (0.6, 3.5, 2.0),
        (0.6, 2.0, -1.6),
    ];
    let mut poses = Vec::new();
    let mut frames = Vec::new();
    for (step, &(x, y, t)) in path.iter().enumerate() {
        let p = pose(x, y, t);
        poses.push(p);
        scan(&world, &mut grid, &p);
        for _ in 0..4 {
            dec.update(&grid, &[]);
        }
        let d = dec.decomposition();
        if [0, 2, 4, 6, 8, 10].contains(&step) {
            frames.push((d.clone(), grid.clone(), nalgebra::Point2::new(x, y), step));
        }
        let doc = svg::render(
            d,
            &grid,
            Some(nalgebra::Point2::new(x, y)),
            &[],
            &format!("step {step}: {} cells", d.cells.len()),
        );
        svg::save_to(&out_dir().join(format!("paper_{step:02}.svg")), &doc).unwrap();
        eprintln!("angle {:?}", dec.locked_angle());
        eprintln!(
            "step {step}: {:?}",
            d.cells
                .iter()
                .map(|c| (
                    c.id.0,
                    c.status,
                    (c.width * 100.0).round() / 100.0,
                    (c.length * 100.0).round() / 100.0
                ))
                .collect::<Vec<_>>()
        );
    }
    // The paper's Fig. 9, our version: six moments of the exploration.
    let view = svg::explored_bounds(&grid);
    let docs = frames
        .iter()
        .map(|(d, g, p, step)| {
            svg::render_view(
                d,
                g,
                Some(*p),
                &[],
                &format!("scan {step}: {} cells", d.cells.len()),
                view,
            )
        })
        .collect();
    let fig = svg::panels(docs, 3, svg::picture_size(view));
    svg::save_to(&out_dir().join("paper_fig9.svg"), &fig).unwrap();
    assert!(dec
        .decomposition()
        .cells
        .iter()
        .any(|c| c.status == CellStatus::Final));
}
