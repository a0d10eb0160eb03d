//! The cut-away setting: camera rays (only they) pass through planes seen
//! from behind.

use clap::Parser;
use penumbra::render::{EditClass, Film, Loaded, SceneDesc, classify};
use penumbra::render::{HitTarget, SEED_ROOM_JSON};

fn room() -> SceneDesc {
    let mut d = SceneDesc::from_json(SEED_ROOM_JSON).unwrap();
    d.camera.width = 64;
    d.camera.height = 36;
    d.render.shadow_rays = 16;
    d
}

fn render(d: &SceneDesc) -> Film {
    Loaded::new(d).unwrap().render_image()
}

/// The seed room with the camera moved out behind its left wall (x < -5
/// or so), still looking at the room's centre.
fn behind_a_wall() -> SceneDesc {
    let mut d = room();
    // Walk the camera left until the centre ray meets a plane from behind.
    for k in 1..200 {
        d.camera.position[0] = -0.25 * k as f64;
        let l = Loaded::new(&d).unwrap();
        let ray = l.scene.camera.ray(32.0, 18.0);
        let blocked = l.scene.closest_hit(&ray);
        let through = l.scene.camera_hit(&ray, true);
        if blocked.map(|h| h.0) != through.map(|h| h.0) {
            return d;
        }
    }
    panic!("no wall found");
}

#[test]
fn a_camera_in_front_of_every_plane_sees_the_same_image() {
    let mut d = room();
    let plain = render(&d);
    d.render.cutaway = true;
    assert_eq!(render(&d), plain);
}

#[test]
fn behind_a_wall_the_camera_sees_through_it_but_only_camera_rays_do() {
    let mut d = behind_a_wall();
    let walled = render(&d);
    d.render.cutaway = true;
    let cut = render(&d);
    assert_ne!(cut, walled);
    // What the centre ray now meets is no plane seen from behind, and it is
    // further away than the wall.
    let l = Loaded::new(&d).unwrap();
    let ray = l.scene.camera.ray(32.0, 18.0);
    let (near, t0) = l.scene.closest_hit(&ray).unwrap();
    let (far, t1) = l.scene.camera_hit(&ray, true).unwrap();
    assert_ne!(near, far);
    assert!(t1 > t0);
    let HitTarget::Object(wall) = near else {
        panic!("the light is no wall")
    };
    assert!(l.scene.objects[wall as usize].bounds.is_none(), "a plane");
    // Shadow and reflected rays still meet every plane: the same scene
    // with the wall deleted renders differently (the wall's shadows and
    // its mirror images are gone there).
    let mut no_wall = d.clone();
    no_wall.render.cutaway = false;
    no_wall.objects.remove(wall as usize);
    let without = render(&no_wall);
    assert_ne!(cut, without, "the wall still shades the room");
}

#[test]
fn cutaway_is_written_only_when_on_and_a_change_is_a_retrace() {
    let d = room();
    assert!(!d.to_json().contains("cutaway"));
    let mut on = d.clone();
    on.render.cutaway = true;
    assert!(on.to_json().contains("\"cutaway\": true"));
    assert_eq!(SceneDesc::from_json(&on.to_json()).unwrap(), on);
    assert_eq!(classify(&d, &on), EditClass::Retrace);
}

#[test]
fn the_cli_takes_cutaway_and_the_viewer_options_without_a_command() {
    let cli = penumbra::cli::Cli::try_parse_from(["penumbra", "--log-timings"]).unwrap();
    assert!(cli.command.is_none() && cli.view.log_timings);
    let cli = penumbra::cli::Cli::try_parse_from(["penumbra", "room.json"]).unwrap();
    assert_eq!(
        cli.view.scene.as_deref(),
        Some(std::path::Path::new("room.json"))
    );
    let cli =
        penumbra::cli::Cli::try_parse_from(["penumbra", "render", "-o", "x.png", "--cutaway"])
            .unwrap();
    match cli.command {
        Some(penumbra::cli::Command::Render(r)) => assert!(r.overrides.cutaway),
        other => panic!("{other:?}"),
    }
}
