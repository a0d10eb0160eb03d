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
}

impl Purpose {
    fn title(self) -> &'static str {
        match self {
            Purpose::OpenScene => "Open scene",
            Purpose::SavePng => "Save PNG",
            Purpose::SaveScene => "Save scene",
            Purpose::OpenReference => "Load reference",
        }
    }
    fn button(self) -> &'static str {
        match self {
            Purpose::OpenScene => "Open",
            Purpose::OpenReference => "Load",
            _ => "Save",
        }
    }
    /// The file kinds listed; the first is the name field's hint.
    fn extensions(self) -> &'static [&'static str] {
        match self {
            Purpose::SavePng => &["png"],
            Purpose::OpenReference => &["exr", "png"],
            _ => &["json"],
        }
    }
    fn opens(self) -> bool {
        matches!(self, Purpose::OpenScene | Purpose::OpenReference)
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
}

pub enum DialogResult {
    Open,
    Cancelled,
    Chosen(Purpose, PathBuf),
}

impl PathDialog {
    /// A dialog starting in the folder of `suggested` (or the current one).
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
        }
    }

    fn full_path(&self) -> PathBuf {
        self.dir.join(self.path.trim())
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
        egui::Window::new(self.purpose.title())
            .open(&mut open)
            .collapsible(false)
            .resizable(true)
            .default_width(460.0)
            .anchor(egui::Align2::CENTER_CENTER, egui::Vec2::ZERO)
            .show(ctx, |ui| {
                ui.label(format!("Folder: {}", self.dir.display()));
                let mut go_up = false;
                let mut enter: Option<String> = None;
                egui::ScrollArea::vertical()
                    .max_height(240.0)
                    .auto_shrink([false, true])
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
                }
                if let Some(name) = enter {
                    self.dir = self.dir.join(name);
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
                ui.horizontal(|ui| {
                    let ok = !self.path.trim().is_empty();
                    confirm |= ui
                        .add_enabled(ok, egui::Button::new(self.purpose.button()))
                        .clicked();
                    if ui.button("Cancel").clicked() {
                        result = DialogResult::Cancelled;
                    }
                });
                if confirm && !self.path.trim().is_empty() {
                    let full = self.full_path();
                    if full.is_dir() {
                        self.dir = full;
                        self.path.clear();
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
