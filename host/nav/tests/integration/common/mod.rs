//! What the navigation tests share.

use ferrobot_nav::OccupancyGrid;

/// A wall along x = 0 (0.1 m thick) with a 0.9 m door at y in [-0.45, 0.45], 2 cm cells.
pub fn wall_with_door() -> OccupancyGrid {
    let mut g = OccupancyGrid::new([-2.0, -2.0], 0.02, 201, 201).expect("grid");
    for j in 0..g.height {
        for i in 0..g.width {
            let c = g.centre(i, j);
            if c[0].abs() <= 0.05 && c[1].abs() > 0.45 {
                g.occupied[j * g.width + i] = true;
            }
        }
    }
    g
}
