//! The window's keys: winit's key events as the walkthrough's commands
//! (see [`crate::command`], which the web page shares).

use winit::keyboard::{Key, ModifiersState, NamedKey};

pub use crate::command::*;

/// The command a key stands for (rholo's letters), if any.
pub fn key(key: &Key, mods: ModifiersState) -> Option<Command> {
    match key {
        Key::Named(NamedKey::Enter) => crate::command::key("Enter", false),
        Key::Named(NamedKey::Escape) => crate::command::key("Escape", false),
        Key::Character(c) => crate::command::key(c.as_str(), mods.control_key()),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn winit_keys_map_to_rholos_letters() {
        let none = ModifiersState::empty();
        assert_eq!(key(&Key::Character("K".into()), none), Some(Command::Kill));
        assert_eq!(key(&Key::Named(NamedKey::Enter), none), Some(Command::Resume));
        assert_eq!(
            key(&Key::Character("r".into()), ModifiersState::CONTROL),
            Some(Command::Redraw)
        );
        assert_eq!(key(&Key::Named(NamedKey::Tab), none), None);
    }
}
