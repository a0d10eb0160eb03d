//! A small path dialog drawn with egui: a path field plus a listing of the
//! folder. It lives inside the frame loop, so the UI never blocks (and no
//! desktop portal is needed).

use std::path::{Path, PathBuf};

/// What the chosen path is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Purpose {
    OpenScene,
    SavePng,
    SaveScene,
    /// A reference image (PNG or EXR) for the error readout.
    OpenReference,
    /// A mesh file to add to the scene.
    AddMesh,
}

impl Purpose {
    fn title(self) -> &'static str {
        match self {
            Purpose::OpenScene => "Open scene",
            Purpose::SavePng => "Save PNG",
            Purpose::SaveScene => "Save scene",
            Purpose::OpenReference => "Load reference",
            Purpose::AddMesh => "Add mesh",
        }
    }
    fn button(self) -> &'static str {
        match self {
            Purpose::OpenScene => "Open",
            Purpose::OpenReference => "Load",
            Purpose::AddMesh => "Add",
            _ => "Save",
        }
    }
    /// The file kinds listed; the first is the name field's hint.
    fn extensions(self) -> &'static [&'static str] {
        match self {
            Purpose::SavePng => &["png", "exr"],
            Purpose::OpenReference => &["exr", "png"],
            Purpose::AddMesh => &super::object_list::MESH_EXTENSIONS,
            _ => &["json"],
        }
    }
    fn opens(self) -> bool {
        matches!(
            self,
            Purpose::OpenScene | Purpose::OpenReference | Purpose::AddMesh
        )
    }
}

pub struct PathDialog {
    pub purpose: Purpose,
    /// The path being typed; relative paths are taken from `dir`.
    pub path: String,
    dir: PathBuf,
    /// Folder listing: (name, is a folder), read when the folder changes.
    entries: Vec<(String, bool)>,
    listed: Option<PathBuf>,
    /// The path field has been given the keyboard once.
    focused: bool,
    /// A save onto this existing file waits for "Replace".
    overwrite: Option<PathBuf>,
    /// A line under the title (what a saved file will hold).
    pub note: Option<String>,
}

pub enum DialogResult {
    Open,
    Cancelled,
    Chosen(Purpose, PathBuf),
}

impl PathDialog {
    /// A dialog starting in the folder of `suggested` (or the current
    /// one), with its file name filled in.
    pub fn new(purpose: Purpose, suggested: &Path) -> PathDialog {
        let cwd = std::env::current_dir().unwrap_or_else(|_| PathBuf::from("."));
        let full = cwd.join(suggested);
        let dir = match full.parent() {
            Some(p) if p.is_dir() => p.to_path_buf(),
            _ => cwd,
        };
        let name = if purpose.opens() && !full.is_file() {
            String::new()
        } else {
            full.file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default()
        };
        PathDialog {
            purpose,
            path: name,
            dir,
            entries: Vec::new(),
            listed: None,
            focused: false,
            overwrite: None,
            note: None,
        }
    }

    /// The folder listed.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// A save waits for confirmation to replace this file.
    pub fn overwrite_pending(&self) -> Option<&Path> {
        self.overwrite.as_deref()
    }

    fn full_path(&self) -> PathBuf {
        self.with_extension(self.dir.join(self.path.trim()))
    }

    /// A saved file without an extension gets the purpose's (as the save
    /// itself would add it), so that the overwrite check sees that name.
    fn with_extension(&self, mut p: PathBuf) -> PathBuf {
        if !self.purpose.opens() && p.extension().is_none() && !p.is_dir() {
            p.set_extension(self.purpose.extensions()[0]);
        }
        p
    }

    fn refresh(&mut self) {
        if self.listed.as_ref() == Some(&self.dir) {
            return;
        }
        let exts = self.purpose.extensions();
        let mut entries: Vec<(String, bool)> = std::fs::read_dir(&self.dir)
            .map(|rd| {
                rd.filter_map(|e| e.ok())
                    .filter_map(|e| {
                        let name = e.file_name().to_string_lossy().into_owned();
                        let is_dir = e.file_type().ok()?.is_dir();
                        let lower = name.to_ascii_lowercase();
                        let shown = !name.starts_with('.')
                            && (is_dir
                                || exts.iter().any(|ext| lower.ends_with(&format!(".{ext}"))));
                        shown.then_some((name, is_dir))
                    })
                    .take(2000)
                    .collect()
            })
            .unwrap_or_default();
        entries.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(&b.0)));
        self.entries = entries;
        self.listed = Some(self.dir.clone());
    }

    pub fn show(&mut self, ctx: &egui::Context) -> DialogResult {
        self.refresh();
        let mut result = DialogResult::Open;
        let mut open = true;
        // One size whatever the folder holds, so that nothing moves under
        // the mouse when the folder changes.
        egui::Window::new(self.purpose.title())
            .open(&mut open)
            .collapsible(false)
            .resizable(false)
            .fixed_size([480.0, 330.0])
            .anchor(egui::Align2::CENTER_CENTER, egui::Vec2::ZERO)
            .show(ctx, |ui| {
                if let Some(n) = &self.note {
                    ui.add(egui::Label::new(n.as_str()).wrap());
                }
                ui.add(egui::Label::new(format!("Folder: {}", self.dir.display())).truncate());
                let mut go_up = false;
                let mut enter: Option<String> = None;
                egui::ScrollArea::vertical()
                    .min_scrolled_height(240.0)
                    .max_height(240.0)
                    .auto_shrink([false, false])
                    .show(ui, |ui| {
                        if ui.selectable_label(false, "../").clicked() {
                            go_up = true;
                        }
                        for (name, is_dir) in &self.entries {
                            let label = if *is_dir {
                                format!("{name}/")
                            } else {
                                name.clone()
                            };
                            let r = ui.selectable_label(self.path == *name, label);
                            if r.clicked() {
                                if *is_dir {
                                    enter = Some(name.clone());
                                } else {
                                    self.path = name.clone();
                                }
                            }
                            if r.double_clicked() && !*is_dir {
                                result = DialogResult::Chosen(self.purpose, self.full_path());
                            }
                        }
                    });
                if go_up && let Some(p) = self.dir.parent() {
                    self.dir = p.to_path_buf();
                    self.overwrite = None;
                }
                if let Some(name) = enter {
                    self.dir = self.dir.join(name);
                    self.overwrite = None;
                }
                ui.separator();
                let mut confirm = false;
                ui.horizontal(|ui| {
                    ui.label("Path");
                    let edit = ui.add(
                        egui::TextEdit::singleline(&mut self.path)
                            .desired_width(320.0)
                            .hint_text(format!("name.{}", self.purpose.extensions()[0])),
                    );
                    if !self.focused {
                        // Type the name right away (over the suggested
                        // one), Enter to confirm.
                        edit.request_focus();
                        let mut state =
                            egui::TextEdit::load_state(ui.ctx(), edit.id).unwrap_or_default();
                        let all = egui::text_selection::CCursorRange::select_all_str(&self.path);
                        state.cursor.set_char_range(Some(all));
                        egui::TextEdit::store_state(ui.ctx(), edit.id, state);
                        self.focused = true;
                    }
                    confirm |= edit.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter));
                });
                // The overwrite question has its row always (empty when
                // not asked), so that the buttons never move.
                if self
                    .overwrite
                    .as_ref()
                    .is_some_and(|e| *e != self.full_path())
                {
                    self.overwrite = None;
                }
                ui.horizontal(|ui| {
                    ui.set_min_height(ui.spacing().interact_size.y);
                    if let Some(existing) = self.overwrite.clone() {
                        ui.colored_label(
                            ui.visuals().warn_fg_color,
                            format!("{} exists.", existing.display()),
                        );
                        if ui.button("Replace").clicked() {
                            result = DialogResult::Chosen(self.purpose, existing);
                        }
                        if ui.button("Keep it").clicked() {
                            self.overwrite = None;
                        }
                    }
                });
                ui.horizontal(|ui| {
                    let ok = !self.path.trim().is_empty() && self.overwrite.is_none();
                    confirm |= ui
                        .add_enabled(ok, egui::Button::new(self.purpose.button()))
                        .clicked();
                    if ui.button("Cancel").clicked() {
                        result = DialogResult::Cancelled;
                    }
                });
                if confirm && !self.path.trim().is_empty() && self.overwrite.is_none() {
                    let full = self.with_extension(self.full_path());
                    if full.is_dir() {
                        self.dir = full;
                        self.path.clear();
                    } else if !self.purpose.opens() && full.exists() {
                        // Ask before replacing a file.
                        self.overwrite = Some(full);
                    } else {
                        result = DialogResult::Chosen(self.purpose, full);
                    }
                }
            });
        if !open || ctx.input(|i| i.key_pressed(egui::Key::Escape)) {
            result = DialogResult::Cancelled;
        }
        result
    }
}
