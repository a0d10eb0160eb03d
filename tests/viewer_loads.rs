//! Scene and mesh files in the viewer are read off the UI thread: frames go on
//! while a load runs, a newer load supersedes an older one, a load can be
//! cancelled, and a FIFO or device in place of a scene is refused with a
//! banner instead of freezing the window. The scene named on the command
//! line, and an edit that needs the scene built again, are built there too.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use egui::accesskit::Role;
mod common;

use common::viewer::{WAIT, harness, harness_of, settle, settled, small_room, step_until};
use egui_kittest::Harness;
use egui_kittest::kittest::Queryable;
use penumbra::app::render_job::JobState;
use penumbra::app::{Viewer, ViewerOptions};
use penumbra::render::{EditClass, SceneDesc};

/// Drops `path` on the window and runs the frame that takes it.
fn drop_file(h: &mut Harness<'static, Viewer>, path: &Path) {
    common::viewer::drop_file(h, path);
    h.step();
}

fn mkfifo(path: &Path) {
    let c = std::ffi::CString::new(path.to_str().unwrap()).unwrap();
    // SAFETY: a NUL-terminated path and a mode, no other pointers.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0, "mkfifo");
}

/// Writes to the FIFO after a while, so that a viewer blocked on it (the
/// bug) comes back and the test fails instead of hanging; `fired` says
/// whether it had to.
fn unblock_later(fifo: PathBuf) -> Arc<AtomicBool> {
    let fired = Arc::new(AtomicBool::new(false));
    let f = fired.clone();
    std::thread::spawn(move || {
        std::thread::sleep(Duration::from_secs(30));
        f.store(true, Ordering::SeqCst);
        if let Ok(mut w) = std::fs::OpenOptions::new().write(true).open(&fifo) {
            use std::io::Write;
            let _ = w.write_all(b"{}");
        }
    });
    fired
}

#[test]
fn a_fifo_in_place_of_the_watched_scene_shows_a_banner_and_frames_go_on() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("room.json");
    std::fs::write(&path, small_room().to_json()).unwrap();
    let mut options = ViewerOptions::new(SceneDesc::load(&path).unwrap());
    options.scene_path = Some(path.clone());
    let mut h = harness(options);
    h.step();
    assert!(h.state().wait_for_render(WAIT));
    h.step();
    let before = h.state().desc().clone();

    // Replaced by a FIFO nobody writes to: the hot reload refuses it.
    std::fs::remove_file(&path).unwrap();
    mkfifo(&path);
    let fired = unblock_later(path.clone());
    step_until(&mut h, |v| v.banner().is_some());
    let banner = h.state().banner().unwrap().to_string();
    assert!(
        !fired.load(Ordering::SeqCst),
        "the viewer waited for the FIFO"
    );
    assert!(
        banner.contains(&format!("{}: a FIFO, not a regular file", path.display())),
        "{banner}"
    );
    h.get_by_label_contains("a FIFO, not a regular file");
    assert_eq!(h.state().desc(), &before);
    assert!(h.state().loading().is_none());

    // Opened by a drop, the same; so is a device.
    h.state_mut().edit(|d, _| d.render.terms.ambient = 0.25);
    for refused in [path.as_path(), Path::new("/dev/zero")] {
        drop_file(&mut h, refused);
        assert!(h.state().wait_for_loads(WAIT));
        h.step();
        assert!(h.state().banner().unwrap().contains("not a regular file"));
        assert_eq!(h.state().desc().render.terms.ambient, 0.25);
    }
    assert!(!fired.load(Ordering::SeqCst));
}

#[test]
fn frames_run_while_a_load_waits_a_newer_load_supersedes_it_and_cancel_keeps_the_scene() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a.json"), dir.path().join("b.json"));
    let mut da = small_room();
    da.render.terms.ambient = 0.5;
    let mut db = small_room();
    db.render.terms.ambient = 2.0;
    std::fs::write(&a, da.to_json()).unwrap();
    std::fs::write(&b, db.to_json()).unwrap();
    let mut h = harness(ViewerOptions::new(small_room()));
    h.step();
    let seed = h.state().desc().clone();

    // The load thread waits (test hook): frames go on, with the progress
    // strip and its Cancel button.
    h.state().hold_loads_for_tests(true);
    drop_file(&mut h, &a);
    for _ in 0..10 {
        h.step();
    }
    let (loading, _, verb) = h.state().loading().expect("a load under way");
    assert_eq!(loading, a.as_path());
    assert_eq!(verb, "loading");
    h.get_by_label_contains(&format!("loading {}…", a.display()));
    assert_eq!(h.state().desc(), &seed);

    // B supersedes A: only B is taken, though A's thread ends too.
    drop_file(&mut h, &b);
    assert_eq!(h.state().loading().unwrap().0, b.as_path());
    h.state().hold_loads_for_tests(false);
    assert!(h.state().wait_for_loads(WAIT));
    h.step();
    h.step();
    assert!(h.state().loading().is_none());
    assert_eq!(h.state().scene_path(), Some(b.as_path()));
    assert_eq!(h.state().desc().render.terms.ambient, 2.0);

    // Cancel: the scene shown stays.
    h.state().hold_loads_for_tests(true);
    drop_file(&mut h, &a);
    h.step();
    h.get_by_role_and_label(Role::Button, "Cancel").click();
    h.step();
    assert!(h.state().loading().is_none());
    h.state().hold_loads_for_tests(false);
    assert!(h.state().wait_for_loads(WAIT));
    h.step();
    assert_eq!(h.state().scene_path(), Some(b.as_path()));
    assert_eq!(h.state().desc().render.terms.ambient, 2.0);
    assert!(h.state().notice().unwrap().contains("cancelled loading"));
}

#[test]
fn a_big_scene_is_read_while_frames_go_on() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("big.json");
    let n = 200_000;
    let mut big = penumbra::render::generate::spheres_in_room(n, 7);
    big.camera.width = 16;
    big.camera.height = 9;
    big.render.shadow_rays = 1;
    std::fs::write(&path, big.to_json()).unwrap();
    let mut h = harness(ViewerOptions::new(small_room()));
    h.step();
    // The frame that takes the drop returns with the file still being
    // read (read on the UI thread, it would have been loaded by then).
    drop_file(&mut h, &path);
    assert!(h.state().loading().is_some(), "the load ran in the frame");
    let mut frames = 0;
    while h.state().loading().is_some() {
        h.step();
        frames += 1;
        std::thread::sleep(Duration::from_millis(5));
        assert!(frames < 100_000);
    }
    assert!(frames > 1, "{frames}");
    assert_eq!(h.state().desc().objects.len(), big.objects.len());
    assert!(h.state().banner().is_none(), "{:?}", h.state().banner());
}

/// A dropped mesh is read on the load thread too: frames go on with the
/// progress strip while the file is read (here held by the test hook), the
/// scene gains the mesh only when the read ends, and Cancel drops it.
#[test]
fn a_dropped_mesh_is_read_while_frames_go_on_and_can_be_cancelled() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("tri.obj");
    std::fs::write(&mesh, "v -1 0 0\nv 1 0 0\nv 0 2 0\nf 1 2 3\n").unwrap();
    let mut h = harness(ViewerOptions::new(small_room()));
    h.step();
    let before = h.state().desc().objects.len();

    h.state().hold_loads_for_tests(true);
    drop_file(&mut h, &mesh);
    for _ in 0..10 {
        h.step();
    }
    let (reading, _, verb) = h.state().loading().expect("a read under way");
    assert_eq!((reading, verb), (mesh.as_path(), "reading mesh"));
    h.get_by_label_contains(&format!("reading mesh {}…", mesh.display()));
    assert_eq!(h.state().desc().objects.len(), before);
    h.state().hold_loads_for_tests(false);
    assert!(h.state().wait_for_loads(WAIT));
    h.step();
    assert!(h.state().loading().is_none());
    assert_eq!(h.state().desc().objects.len(), before + 1);
    assert!(h.state().notice().unwrap().contains("added"));

    // Cancelled: the scene stays as it was.
    h.state().hold_loads_for_tests(true);
    drop_file(&mut h, &mesh);
    h.step();
    h.get_by_role_and_label(Role::Button, "Cancel").click();
    h.step();
    h.state().hold_loads_for_tests(false);
    assert!(h.state().wait_for_loads(WAIT));
    h.step();
    assert_eq!(h.state().desc().objects.len(), before + 1);
}

/// `name` in `dir`: the small room with a mesh of `mesh`, a file beside
/// it, as its last object.
fn room_with_mesh(dir: &Path, name: &str, mesh: &str) -> PathBuf {
    let path = dir.join(name);
    let mut json: serde_json::Value = serde_json::from_str(&small_room().to_json()).unwrap();
    json["objects"]
        .as_array_mut()
        .unwrap()
        .push(serde_json::json!({"type": "mesh", "file": mesh, "material": "white"}));
    std::fs::write(&path, json.to_string()).unwrap();
    path
}

/// The render's latest image, once it finished, and the cost class of the
/// edit that made it.
fn finished_render(v: &Viewer) -> (penumbra::render::Film, EditClass) {
    match v.render_state() {
        Some(JobState::Finished(f)) => ((*f.film).clone(), f.class),
        other => panic!("render did not finish: {other:?}"),
    }
}

fn core_render(desc: &SceneDesc) -> penumbra::render::Film {
    penumbra::render::Loaded::new(desc).unwrap().render_image()
}

/// `penumbra scene.json`: the scene named on the command line is read and
/// built on the load thread under the loading strip, as one opened from
/// the File menu (it was read before the window opened, and its meshes by
/// the render worker with no strip: a big mesh showed nothing for
/// seconds). Frames go on meanwhile, nothing else renders, and the render
/// traces over the scene the loader built.
#[test]
fn a_scene_named_on_the_command_line_is_built_under_the_loading_strip() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("box.obj"), common::box_obj([1.0; 3])).unwrap();
    let path = room_with_mesh(dir.path(), "withmesh.json", "box.obj");
    let args = penumbra::cli::ViewArgs {
        scene: Some(path.clone()),
        refine_spp: Some(1),
        ..Default::default()
    };
    let viewer = Viewer::new(ViewerOptions::from_args(&args).expect("the viewer starts"));
    // The load thread waits (test hook), whatever the machine's speed.
    viewer.hold_loads_for_tests(true);
    let mut h = harness_of(viewer);
    for _ in 0..10 {
        h.step();
    }
    let (loading, _, verb) = h
        .state()
        .loading()
        .expect("the scene loads on the load thread");
    assert_eq!((loading, verb), (path.as_path(), "loading"));
    h.get_by_label_contains(&format!("loading {}…", path.display()));
    h.get_by_role_and_label(Role::Button, "Cancel");
    assert_eq!(
        h.state().renders_started(),
        0,
        "something rendered meanwhile"
    );
    assert!(h.state().title().starts_with("withmesh.json"));

    h.state().hold_loads_for_tests(false);
    assert!(h.state().wait_for_loads(WAIT));
    h.step();
    assert!(h.state().loading().is_none());
    assert_eq!(h.state().scene_path(), Some(path.as_path()));
    assert!(h.state().banner().is_none(), "{:?}", h.state().banner());
    settle(&mut h);
    // Traced over the loader's scene, not built again by the worker.
    let (film, class) = finished_render(h.state());
    assert_eq!(class, EditClass::Retrace);
    assert_eq!(film, core_render(&SceneDesc::load(&path).unwrap()));

    // Cancelled at launch: the seed room, rendered, and no file named.
    let viewer = Viewer::new(ViewerOptions::from_args(&args).unwrap());
    viewer.hold_loads_for_tests(true);
    let mut h = harness_of(viewer);
    h.step();
    h.get_by_role_and_label(Role::Button, "Cancel").click();
    h.step();
    assert!(h.state().loading().is_none());
    h.state().hold_loads_for_tests(false);
    settle(&mut h);
    assert_eq!(h.state().scene_path(), None);
    assert_eq!(
        h.state().desc(),
        &SceneDesc::from_json(penumbra::render::SEED_ROOM_JSON).unwrap()
    );
    assert!(h.state().renders_started() > 0);
    assert!(h.state().notice().unwrap().contains("cancelled loading"));
}

/// An edit that needs the scene built again (here a mesh's file) is built
/// on the load thread under the strip, with the render on the scene
/// before until it is (the worker read the mesh itself, with no strip);
/// one that does not build leaves the scene before it, with a banner
/// naming the field, and Cancel does the same without one.
#[test]
fn an_edit_that_rebuilds_the_scene_is_built_under_the_loading_strip_or_refused() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("a.obj"), common::box_obj([1.0; 3])).unwrap();
    std::fs::write(dir.path().join("b.obj"), common::box_obj([0.5, 2.0, 0.5])).unwrap();
    let path = room_with_mesh(dir.path(), "room.json", "a.obj");
    let desc = SceneDesc::load(&path).unwrap();
    let mesh = desc.objects.len() - 1;
    let set_mesh = |d: &mut SceneDesc, file: &str| match &mut d.objects[mesh] {
        penumbra::render::scene_file::ObjectDesc::Mesh(m) => m.file = file.into(),
        other => panic!("not a mesh: {other:?}"),
    };
    let mut options = ViewerOptions::new(desc.clone());
    options.scene_path = Some(path.clone());
    let mut h = settled(options);
    let generation = h.state().render_generation();

    h.state().hold_loads_for_tests(true);
    h.state_mut().edit(|d, _| set_mesh(d, "b.obj"));
    for _ in 0..10 {
        h.step();
    }
    let (_, _, verb) = h
        .state()
        .loading()
        .expect("the edit builds on the load thread");
    assert_eq!(verb, "building");
    h.get_by_label_contains(&format!("building {}…", path.display()));
    assert_eq!(
        h.state().render_generation(),
        generation,
        "the worker got it"
    );
    h.state().hold_loads_for_tests(false);
    settle(&mut h);
    let mut edited = desc.clone();
    set_mesh(&mut edited, "b.obj");
    assert_eq!(h.state().desc(), &edited);
    let (film, class) = finished_render(h.state());
    assert_eq!(class, EditClass::Retrace);
    assert_eq!(film, core_render(&edited));

    // A file that is not there: the scene before stays, rendered, and the
    // banner names the field.
    h.state_mut().edit(|d, _| set_mesh(d, "nope.obj"));
    settle(&mut h);
    let banner = h.state().banner().expect("a banner").to_string();
    assert!(
        banner.contains(&format!("objects[{mesh}].file")) && banner.contains("nope.obj"),
        "{banner}"
    );
    h.get_by_label_contains("does not build");
    assert_eq!(h.state().desc(), &edited);
    assert_eq!(finished_render(h.state()).0, film);

    // Cancelled: the same, without a banner.
    h.get_by_role_and_label(Role::Button, "Dismiss").click();
    h.step();
    h.state().hold_loads_for_tests(true);
    h.state_mut().edit(|d, _| set_mesh(d, "a.obj"));
    h.step();
    h.get_by_role_and_label(Role::Button, "Cancel").click();
    h.step();
    h.state().hold_loads_for_tests(false);
    settle(&mut h);
    assert_eq!(h.state().desc(), &edited);
    assert!(h.state().banner().is_none());
    assert!(h.state().notice().unwrap().contains("cancelled building"));
    assert_eq!(finished_render(h.state()).0, film);

    // With an object hidden (left out of the scene built): the banner
    // names the mesh by its place in the scene, which comes back whole.
    h.state_mut().edit(|_, v| v.hidden = vec![0]);
    settle(&mut h);
    let shown = h.state().render_desc();
    assert_eq!(finished_render(h.state()).0, core_render(&shown));
    h.state_mut().edit(|d, _| set_mesh(d, "nope.obj"));
    settle(&mut h);
    let banner = h.state().banner().expect("a banner").to_string();
    assert!(
        banner.contains(&format!("objects[{mesh}].file")),
        "{banner}"
    );
    assert_eq!(h.state().desc(), &edited);
    assert_eq!(h.state().view_settings().hidden, vec![0]);
    assert_eq!(h.state().render_desc(), shown);
}

/// While a load runs (here an edit's build), the render of the scene
/// shown pauses, its image kept: its passes and refinement took the cores
/// the load needs, for an image about to be replaced. Once the load is
/// cancelled (or fails) the scene shown stays and its refinement goes on.
#[test]
fn the_render_pauses_while_a_load_runs_and_goes_on_once_it_is_cancelled() {
    let mut options = ViewerOptions::new(small_room());
    // Refines for longer than the test runs.
    options.refine_spp = 1 << 16;
    let mut h = settled(options);
    let tiles = h.state().render_tiles_delivered();
    step_until(&mut h, |v| v.render_tiles_delivered() > tiles);

    h.state().hold_loads_for_tests(true);
    h.state_mut().edit(|_, v| v.hidden = vec![0]);
    h.step();
    assert!(h.state().loading().is_some(), "the edit builds");
    // Tiles under way when it paused may still arrive.
    std::thread::sleep(Duration::from_millis(300));
    h.step();
    let tiles = h.state().render_tiles_delivered();
    let image = h.state().shown_image().clone();
    for _ in 0..10 {
        std::thread::sleep(Duration::from_millis(50));
        h.step();
    }
    assert_eq!(
        h.state().render_tiles_delivered(),
        tiles,
        "the render went on during the load"
    );
    assert_eq!(h.state().shown_image(), &image);

    h.get_by_role_and_label(Role::Button, "Cancel").click();
    h.step();
    h.state().hold_loads_for_tests(false);
    assert!(h.state().view_settings().hidden.is_empty());
    step_until(&mut h, |v| v.render_tiles_delivered() > tiles);
}

/// An edit that needs the scene built again and does not build (or whose
/// build is cancelled) is no undo step: Undo goes back past it to the
/// edit before, which took effect (it went back to the failed edit).
#[test]
fn an_edit_whose_build_fails_or_is_cancelled_is_not_undone() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("a.obj"), common::box_obj([1.0; 3])).unwrap();
    let path = room_with_mesh(dir.path(), "room.json", "a.obj");
    let desc = SceneDesc::load(&path).unwrap();
    let mesh = desc.objects.len() - 1;
    let set_mesh = move |d: &mut SceneDesc, file: &str| match &mut d.objects[mesh] {
        penumbra::render::scene_file::ObjectDesc::Mesh(m) => m.file = file.into(),
        other => panic!("not a mesh: {other:?}"),
    };
    let mut options = ViewerOptions::new(desc.clone());
    options.scene_path = Some(path.clone());
    let mut h = settled(options);
    h.state_mut().edit(|d, _| d.render.terms.ambient = 0.5);
    settle(&mut h);
    let edited = h.state().desc().clone();

    // Fails (frames run while it builds, as when a person edits): the
    // scene before it stays, and so does the history.
    h.state().hold_loads_for_tests(true);
    h.state_mut().edit(|d, _| set_mesh(d, "nope.obj"));
    h.step();
    h.step();
    h.state().hold_loads_for_tests(false);
    settle(&mut h);
    assert!(h.state().banner().is_some());
    assert_eq!(h.state().desc(), &edited);
    assert!(h.state_mut().undo());
    assert_eq!(h.state().desc(), &desc);
    assert!(h.state_mut().redo());
    assert_eq!(h.state().desc(), &edited);
    settle(&mut h);

    // Cancelled: the same.
    h.state().hold_loads_for_tests(true);
    h.state_mut().edit(|_, v| v.hidden = vec![0]);
    h.step();
    h.get_by_role_and_label(Role::Button, "Cancel").click();
    h.step();
    h.state().hold_loads_for_tests(false);
    settle(&mut h);
    assert!(h.state().view_settings().hidden.is_empty());
    assert!(h.state_mut().undo());
    assert_eq!(h.state().desc(), &desc);
    settle(&mut h);

    // Undone while it builds: dropped, and the redo is still there.
    h.state().hold_loads_for_tests(true);
    h.state_mut().edit(|_, v| v.hidden = vec![0]);
    h.step();
    assert!(h.state_mut().undo());
    h.step();
    h.state().hold_loads_for_tests(false);
    settle(&mut h);
    assert!(h.state().view_settings().hidden.is_empty());
    assert_eq!(h.state().desc(), &desc);
    assert!(h.state_mut().redo());
    assert_eq!(h.state().desc(), &edited);
    settle(&mut h);
}

/// A render that fails on an object names it by its place in the scene
/// (and the object list), hidden objects counted: the render's scene
/// leaves them out, and named it by its place there.
#[test]
fn a_failed_render_names_the_object_by_its_place_in_the_scene() {
    let dir = tempfile::tempdir().unwrap();
    let path = room_with_mesh(dir.path(), "room.json", "nope.obj");
    let desc = SceneDesc::load(&path).unwrap();
    let mesh = desc.objects.len() - 1;
    let mut viewer = Viewer::new(ViewerOptions::new(desc));
    // The first render, built by the render worker, without the first
    // object.
    viewer.edit(|_, v| v.hidden = vec![0]);
    let mut h = harness_of(viewer);
    step_until(&mut h, |v| v.banner().is_some());
    let banner = h.state().banner().unwrap().to_string();
    assert!(
        banner.contains(&format!("objects[{mesh}].file")),
        "{banner}"
    );
}
