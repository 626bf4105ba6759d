//! The faces the statistics loss compares one by one, on a dev scene: dev_4's table, whose crop
//! holds its top and its front, has two, the top carrying most of the weight; its floor and its
//! plaster wall, each one plane, have one.

mod dev_part_views;
#[path = "../../tests/src/not_run.rs"]
mod not_run;

use psc_fit::loss::Moments;

/// Each face's share of the crop's weight, largest first.
fn face_shares(part: &dev_part_views::DevPart) -> Vec<f32> {
    let v = &part.view;
    assert_eq!(v.faces.len(), v.weight.len(), "{}: one face per crop pixel", part.name);
    let weights: Vec<f32> = Moments::by_face(&v.target, &v.weight, &v.faces).into_iter().map(|(_, w)| w).collect();
    let total: f32 = weights.iter().sum();
    let mut shares: Vec<f32> = weights.iter().filter(|&&w| w > 0.0).map(|w| w / total).collect();
    shares.sort_by(|a, b| b.total_cmp(a));
    shares
}

#[test]
fn a_table_has_a_top_and_a_front_and_a_wall_is_one_face() {
    let Some(parts) = dev_part_views::first_view_parts("dev_4", "faces_dev", 2000) else { return };
    let shares = |name: &str| {
        let part = parts.iter().find(|p| p.name == name).unwrap_or_else(|| panic!("{name} is seen"));
        face_shares(part)
    };
    let table = shares("table_Wood_013_COLOR");
    eprintln!("table faces {table:?}");
    assert_eq!(table.len(), 2, "table: {table:?}");
    assert!(table[0] > 0.5 && table[1] > 0.05, "table: {table:?}");
    for plane in ["floor", "walls_a"] {
        assert_eq!(shares(plane), vec![1.0], "{plane}");
    }
}
