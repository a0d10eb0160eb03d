//! Anti-aliasing: several camera samples per pixel, placed by the filter.

use penumbra::render::{CancelToken, FilterKind, Loaded, RenderOptions, SEED_ROOM_JSON, SceneDesc};

fn room(width: u32, height: u32, spp: u32) -> SceneDesc {
    let mut d = SceneDesc::from_json(SEED_ROOM_JSON).unwrap();
    d.camera.width = width;
    d.camera.height = height;
    d.render.samples_per_pixel = spp;
    d.render.shadow_rays = 16;
    d
}

fn render(loaded: &Loaded, threads: usize, tile: u32, progressive: bool) -> Vec<[u32; 3]> {
    let options = RenderOptions {
        threads: Some(threads),
        progressive,
        tile_size: tile,
    };
    loaded
        .render(&options, &CancelToken::new(), &|_| {})
        .unwrap()
        .film
        .pixels
        .iter()
        .map(|p| p.to_array().map(f32::to_bits))
        .collect()
}

#[test]
fn several_samples_are_deterministic_across_threads_tiles_and_passes() {
    let loaded = Loaded::new(&room(61, 37, 9)).unwrap();
    let one = render(&loaded, 1, 16, false);
    for (threads, tile, progressive) in [(2, 8, false), (3, 24, true), (5, 40, false)] {
        assert!(
            render(&loaded, threads, tile, progressive) == one,
            "{threads} threads, tile {tile}, progressive {progressive}"
        );
    }
}

#[test]
fn one_sample_is_the_ray_through_the_pixel_centre() {
    // spp 1 ignores the filter: the image of a render before anti-aliasing.
    let mut a = Loaded::new(&room(40, 24, 1)).unwrap();
    let reference = render(&a, 2, 16, false);
    a.settings.filter = FilterKind::Box;
    assert!(render(&a, 2, 16, false) == reference);
}

#[test]
fn more_samples_cost_no_more_than_their_count_of_rays() {
    let d = room(32, 18, 7);
    let report = Loaded::new(&d)
        .unwrap()
        .render(&RenderOptions::default(), &CancelToken::new(), &|_| {})
        .unwrap();
    assert_eq!(
        report.stats.camera,
        32 * 18 * 7,
        "one camera ray per sample"
    );
}

/// A wall whose colour is 1 where it covers the image and black elsewhere
/// (ambient only), its left edge crossing pixel column 10 at `edge` (in
/// pixels from the image's left side).
fn edge_scene(edge: f64, spp: u32) -> SceneDesc {
    let (width, height) = (24u32, 8u32);
    let fov: f64 = 60.0;
    let half_h = (fov.to_radians() / 2.0).tan();
    let half_w = half_h * width as f64 / height as f64;
    // A point (x, y, −1) is seen at image column (x / half_w + 1) · width / 2.
    let x0 = (2.0 * edge / width as f64 - 1.0) * half_w;
    let json = format!(
        r#"{{
        "format": 1,
        "camera": {{ "position": [0, 0, 0], "look_at": [0, 0, -1], "up": [0, 1, 0],
                    "fov_y_deg": {fov}, "width": {width}, "height": {height} }},
        "render": {{ "shadow_rays": 1, "max_depth": 1, "samples_per_pixel": {spp} }},
        "light": {{ "corner": [-0.1, 5, 5], "edge_u": [0.2, 0, 0], "edge_v": [0, 0, 0.2],
                   "ambient": [1, 1, 1], "diffuse": [0, 0, 0], "specular": [0, 0, 0] }},
        "materials": {{ "wall": {{ "ambient": [1, 1, 1], "diffuse": [0, 0, 0],
                       "specular": [0, 0, 0], "shininess": 1, "reflectivity": 0 }} }},
        "objects": [
            {{ "type": "rect", "corner": [{x0}, -10, -1], "edge_u": [20, 0, 0],
               "edge_v": [0, 20, 0], "material": "wall" }}
        ]
    }}"#
    );
    SceneDesc::from_json(&json).unwrap()
}

#[test]
fn an_edge_pixel_converges_to_the_area_the_wall_covers() {
    for (edge, covered) in [(10.3, 0.7), (10.5, 0.5), (10.85, 0.15)] {
        let mut errors = Vec::new();
        for spp in [4, 64, 256] {
            let mut loaded = Loaded::new(&edge_scene(edge, spp)).unwrap();
            loaded.settings.filter = FilterKind::Box;
            let film = loaded.render_image();
            let v = film.get(10, 4).x as f64;
            errors.push((v - covered).abs());
            // Neighbours: fully covered on the right, empty on the left.
            assert_eq!(film.get(12, 4).x, 1.0);
            assert_eq!(film.get(8, 4).x, 0.0);
        }
        assert!(errors[2] < 0.01, "edge {edge}: errors {errors:?}");
        assert!(
            errors[2] <= errors[0],
            "edge {edge}: no convergence {errors:?}"
        );
    }
    // One sample: the pixel centre decides (10.3: the centre 10.5 is covered).
    let film = Loaded::new(&edge_scene(10.3, 1)).unwrap().render_image();
    assert_eq!(film.get(10, 4).x, 1.0);
}

#[test]
fn the_smooth_filter_weighs_an_edge_by_its_profile() {
    // Blackman–Harris 1.5 px: an edge through the pixel centre still gives
    // half (the filter is symmetric), and an edge 0.5 px to the left of the
    // pixel's own square already reaches into it (its support is wider).
    let film = Loaded::new(&edge_scene(10.5, 256)).unwrap().render_image();
    assert!(
        (film.get(10, 4).x - 0.5).abs() < 0.01,
        "{}",
        film.get(10, 4).x
    );
    let film = Loaded::new(&edge_scene(11.1, 256)).unwrap().render_image();
    let v = film.get(10, 4).x;
    assert!(v > 0.0 && v < 0.05, "{v}");
}
