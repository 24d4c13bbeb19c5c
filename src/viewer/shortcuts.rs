//! The viewer's keyboard shortcuts, in one table ([`SHORTCUTS`]): each row is one line of the
//! help (the keys as written there, what they do) and the bindings that do it. The key handling
//! ([`handle`]), the flip view's held key ([`held`]) and the help overlay all iterate this
//! table, so the help cannot disagree with the keys. A new shortcut is one row here and, when it
//! does something new, one [`Action`] and its line in [`apply`].

use eframe::egui::{self, Key, Modifiers};

use super::controller::{CompareMode, Controller};
use super::window_shot::WindowShot;

/// What a key does. When several keys arrive in one frame their actions run in this order
/// (a mode first, a measurement or a save last, of the camera as just reset).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Action {
    SetMode(CompareMode),
    TogglePlay,
    ToggleHelp,
    ResetCamera,
    FewerChannels,
    MoreChannels,
    NextTechnique,
    MeasureNow,
    SaveWindow,
    SaveView,
    /// Held, not pressed: the flip view shows B while the key is down.
    ShowB,
}

/// One key (with the modifiers it needs) and what it does.
#[derive(Clone, Copy, Debug)]
pub struct Binding {
    pub key: Key,
    /// `NONE` matches the key with any modifiers; anything else must be held with it.
    pub modifiers: Modifiers,
    pub action: Action,
}

/// One line of the help and the keys behind it.
#[derive(Clone, Copy, Debug)]
pub struct Shortcut {
    /// The keys as the help writes them.
    pub keys: &'static str,
    pub description: &'static str,
    pub bindings: &'static [Binding],
}

const fn key(key: Key, action: Action) -> Binding {
    Binding {
        key,
        modifiers: Modifiers::NONE,
        action,
    }
}

/// Every keyboard shortcut, in the help's order.
pub const SHORTCUTS: &[Shortcut] = &[
    Shortcut {
        keys: "1 .. 6",
        description: "single, split, side by side, flip, difference x4, FLIP map",
        bindings: &[
            key(Key::Num1, Action::SetMode(CompareMode::Single)),
            key(Key::Num2, Action::SetMode(CompareMode::Split)),
            key(Key::Num3, Action::SetMode(CompareMode::SideBySide)),
            key(Key::Num4, Action::SetMode(CompareMode::Flip)),
            key(Key::Num5, Action::SetMode(CompareMode::Difference)),
            key(Key::Num6, Action::SetMode(CompareMode::FlipMap)),
            key(Key::Num7, Action::SetMode(CompareMode::Motion)),
        ],
    },
    Shortcut {
        keys: "B (hold)",
        description: "show B in flip mode",
        bindings: &[key(Key::B, Action::ShowB)],
    },
    Shortcut {
        keys: "Space",
        description: "play / pause the simulation",
        bindings: &[key(Key::Space, Action::TogglePlay)],
    },
    Shortcut {
        keys: "[  ]",
        description: "A: one channel fewer / more",
        bindings: &[
            key(Key::OpenBracket, Action::FewerChannels),
            key(Key::CloseBracket, Action::MoreChannels),
        ],
    },
    Shortcut {
        keys: "T",
        description: "A: next technique",
        bindings: &[key(Key::T, Action::NextTechnique)],
    },
    Shortcut {
        keys: "E",
        description: "measure A against exact now",
        bindings: &[key(Key::E, Action::MeasureNow)],
    },
    Shortcut {
        keys: "S",
        description: "save A at full size as PNG",
        bindings: &[key(Key::S, Action::SaveView)],
    },
    Shortcut {
        keys: "Ctrl+S",
        description: "save the whole window as PNG",
        bindings: &[Binding {
            key: Key::S,
            modifiers: Modifiers::COMMAND,
            action: Action::SaveWindow,
        }],
    },
    Shortcut {
        keys: "R",
        description: "reset the camera",
        bindings: &[key(Key::R, Action::ResetCamera)],
    },
    Shortcut {
        keys: "H, F1",
        description: "this help",
        bindings: &[
            key(Key::H, Action::ToggleHelp),
            key(Key::F1, Action::ToggleHelp),
        ],
    },
];

/// What the mouse does in the viewport, for the help (after the keys).
pub const MOUSE: &[(&str, &str)] = &[
    ("drag", "orbit the camera (in split view, drag the divider)"),
    ("right / middle drag", "pan"),
    ("wheel", "zoom"),
    ("drag the yellow ring", "move where the spotlight aims"),
    ("shift + drag", "move the spotlight around its target"),
    ("click", "probe T along the light ray through the point"),
];

fn bindings() -> impl Iterator<Item = &'static Binding> {
    SHORTCUTS.iter().flat_map(|s| s.bindings)
}

/// Runs the actions of the keys pressed this frame (none while a text field has the keyboard).
pub fn handle(controller: &mut Controller, window_shot: &WindowShot, ctx: &egui::Context) {
    if ctx.egui_wants_keyboard_input() {
        return;
    }
    let mut fired = Vec::new();
    // Shortcuts with modifiers first, and their key is then not also a plain press: Ctrl+S
    // saves the window, not the view as well.
    let mut consumed = Vec::new();
    for b in bindings().filter(|b| b.modifiers != Modifiers::NONE && b.action != Action::ShowB) {
        let shortcut = egui::KeyboardShortcut::new(b.modifiers, b.key);
        if ctx.input_mut(|i| i.consume_shortcut(&shortcut)) {
            fired.push(b.action);
            consumed.push(b.key);
        }
    }
    for b in bindings().filter(|b| b.modifiers == Modifiers::NONE && b.action != Action::ShowB) {
        if !consumed.contains(&b.key) && ctx.input(|i| i.key_pressed(b.key)) {
            fired.push(b.action);
        }
    }
    fired.sort();
    fired.dedup();
    for &action in &fired {
        // `[` and `]` in one frame: one channel fewer, as `[` wins.
        if action == Action::MoreChannels && fired.contains(&Action::FewerChannels) {
            continue;
        }
        apply(controller, window_shot, ctx, action);
    }
}

/// Does what `action` says.
pub fn apply(
    controller: &mut Controller,
    window_shot: &WindowShot,
    ctx: &egui::Context,
    action: Action,
) {
    match action {
        Action::SetMode(mode) => controller.state.mode = mode,
        Action::TogglePlay => controller.toggle_play(),
        Action::ToggleHelp => controller.toggle_help(),
        Action::ResetCamera => controller.reset_camera(),
        Action::FewerChannels => controller.fewer_channels(),
        Action::MoreChannels => controller.more_channels(),
        Action::NextTechnique => controller.next_technique(),
        Action::MeasureNow => controller.measure_now(),
        Action::SaveWindow => window_shot.save(ctx, controller),
        Action::SaveView => controller.save_viewport(),
        Action::ShowB => {}
    }
}

/// Whether a key bound to `action` is held down (and no text field has the keyboard).
pub fn held(ctx: &egui::Context, action: Action) -> bool {
    bindings()
        .filter(|b| b.action == action)
        .any(|b| ctx.input(|i| i.key_down(b.key)))
        && !ctx.egui_wants_keyboard_input()
}
