//! The worked example of the material guide (docs/materials.md) is the library's
//! `striped_wallpaper` graph, byte for byte, so the guide cannot drift from a graph that the
//! library tests check.

use std::path::Path;

#[test]
fn the_guide_example_is_the_library_graph() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let guide = std::fs::read_to_string(root.join("docs/materials.md")).expect("docs/materials.md");
    let marker = "```\nimport std.noise;\nimport std.patterns;\nimport std.transform;\n\n/// Striped wallpaper";
    let start = guide.find(marker).expect("the guide shows the striped_wallpaper graph") + 4;
    let end = start + guide[start..].find("```").expect("the block is closed");
    let graph = std::fs::read_to_string(root.join("graphs/wallpaper/striped_wallpaper.psg")).expect("the graph");
    assert_eq!(&guide[start..end], graph, "docs/materials.md and graphs/wallpaper/striped_wallpaper.psg differ");
}
