//! The viewer's keys and mouse (README "Viewer keys"): what a frame's [`Input`] asks for.

use minifb::Key;

use super::camera::CameraInput;
use super::input::Input;

/// A request besides moving the camera.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Command {
    /// Filter by number: 0 none, 1.. the registered filters in order.
    Filter(usize),
    NextFilter,
    ToggleHoles,
    /// Kernel width steps (each ±2, the width stays odd).
    KernelWidth(i32),
    ToggleUnfiltered,
    ToggleError,
    /// Next (+1) or previous (−1) AOV picture, after the last back to the image.
    Aov(i32),
    /// Exposure of the display, in half stops.
    Exposure(i32),
    Screenshot,
    SaveScene,
    ResetCamera,
    ToggleHelp,
    Quit,
}

/// The keys and what they do, for the help overlay (README "Viewer keys" lists the same).
pub const HELP: &[&str] = &[
    "W/S or Up/Down: forward/back   A/D or Left/Right: sideways   E/Q or PageUp/PageDown: up/down",
    "Shift: 4x faster   Ctrl: 4x slower   left drag: look   left or right click: focus there",
    "wheel or Z/X: field of view   Comma/Period: focal distance   [ ]: aperture (lens radius)",
    "Tab: next filter   0: none   1-9: filter by number   H: holes   J/K: kernel width -/+",
    "U: unfiltered   R: error against the cached reference   M/N: AOVs next/previous",
    "-/=: exposure   P: screenshot   O: save the camera as a scene file   Home: reset camera",
    "F1: this help   Esc: quit",
];

/// Mouse movement below which a press and release is a click (autofocus), not a drag.
const CLICK_SLOP: f32 = 3.0;

/// What one frame of input asks for.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Requests {
    pub camera: CameraInput,
    pub commands: Vec<Command>,
    /// Focus on the surface under this window pixel.
    pub focus_at: Option<(f32, f32)>,
}

/// Reads frames of input; remembers the mouse between frames (drags, clicks).
#[derive(Clone, Debug, Default)]
pub struct Controls {
    last: Input,
    /// Where the left button went down, and whether the cursor has since moved (a drag).
    press: Option<((f32, f32), bool)>,
}

impl Controls {
    pub fn read(&mut self, input: &Input) -> Requests {
        let held = |keys: &[Key]| keys.iter().any(|k| input.held.contains(k));
        let axis =
            |plus: &[Key], minus: &[Key]| held(plus) as i32 as f32 - held(minus) as i32 as f32;
        let mut r = Requests::default();
        r.camera.forward = axis(&[Key::W, Key::Up], &[Key::S, Key::Down]);
        r.camera.strafe = axis(&[Key::D, Key::Right], &[Key::A, Key::Left]);
        r.camera.lift = axis(&[Key::E, Key::PageUp], &[Key::Q, Key::PageDown]);
        r.camera.speed = if held(&[Key::LeftShift, Key::RightShift]) {
            4.0
        } else if held(&[Key::LeftCtrl, Key::RightCtrl]) {
            0.25
        } else {
            1.0
        };
        // Scrolling away from the user zooms in (a narrower field of view).
        if input.scroll != 0.0 {
            r.camera.fov_steps -= input.scroll.signum() as i32;
        }
        for &k in &input.pressed {
            match k {
                Key::Z => r.camera.fov_steps -= 1,
                Key::X => r.camera.fov_steps += 1,
                Key::Comma => r.camera.focus_steps -= 1,
                Key::Period => r.camera.focus_steps += 1,
                Key::LeftBracket => r.camera.aperture_steps -= 1,
                Key::RightBracket => r.camera.aperture_steps += 1,
                _ => r.commands.extend(command(k)),
            }
        }
        self.mouse(input, &mut r);
        if input.quit {
            r.commands.push(Command::Quit);
        }
        self.last = input.clone();
        r
    }

    fn mouse(&mut self, input: &Input, r: &mut Requests) {
        let (now, before) = (input.mouse, self.last.mouse);
        if input.left && self.last.left {
            if let (Some(a), Some(b)) = (now, before) {
                let d = (a.0 - b.0, a.1 - b.1);
                if d != (0.0, 0.0) {
                    r.camera.drag = d;
                }
                if let Some((start, moved)) = &mut self.press {
                    *moved |= (a.0 - start.0).abs().max((a.1 - start.1).abs()) > CLICK_SLOP;
                }
            }
        } else if input.left {
            self.press = now.map(|p| (p, false));
        } else if self.last.left {
            // Released: without a drag it was a click.
            if let (Some((_, false)), Some(p)) = (self.press.take(), now) {
                r.focus_at = Some(p);
            }
        }
        if input.right && !self.last.right {
            r.focus_at = now.or(r.focus_at);
        }
    }
}

fn command(k: Key) -> Option<Command> {
    let digits = [
        Key::Key0,
        Key::Key1,
        Key::Key2,
        Key::Key3,
        Key::Key4,
        Key::Key5,
        Key::Key6,
        Key::Key7,
        Key::Key8,
        Key::Key9,
    ];
    if let Some(n) = digits.iter().position(|d| *d == k) {
        return Some(Command::Filter(n));
    }
    Some(match k {
        Key::Tab => Command::NextFilter,
        Key::H => Command::ToggleHoles,
        Key::J => Command::KernelWidth(-1),
        Key::K => Command::KernelWidth(1),
        Key::U => Command::ToggleUnfiltered,
        Key::R => Command::ToggleError,
        Key::M => Command::Aov(1),
        Key::N => Command::Aov(-1),
        Key::Minus => Command::Exposure(-1),
        Key::Equal => Command::Exposure(1),
        Key::P => Command::Screenshot,
        Key::O => Command::SaveScene,
        Key::Home => Command::ResetCamera,
        Key::F1 => Command::ToggleHelp,
        Key::Escape => Command::Quit,
        _ => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::view::input::Script;

    fn requests(script: &str, frames: u32) -> Vec<Requests> {
        let mut s = Script::parse(script).unwrap();
        let mut c = Controls::default();
        (0..frames).map(|f| c.read(&s.input(f))).collect()
    }

    #[test]
    fn keys_move_and_command() {
        let r = requests(
            "0 press W\n0 press LeftShift\n1 tap Key2\n1 tap RightBracket\n",
            3,
        );
        assert_eq!(r[0].camera.forward, 1.0);
        assert_eq!(r[0].camera.speed, 4.0);
        assert_eq!(r[1].commands, [Command::Filter(2)]);
        assert_eq!(r[1].camera.aperture_steps, 1);
        assert!(r[2].commands.is_empty() && r[2].camera.forward == 1.0);
    }

    #[test]
    fn a_drag_looks_and_a_click_focuses() {
        let r = requests("0 move 50 50\n1 drag 20 0\n5 click 7 9\n", 8);
        assert_eq!(r[2].camera.drag, (20.0, 0.0));
        assert!(
            r.iter().take(5).all(|q| q.focus_at.is_none()),
            "a drag is no click"
        );
        assert_eq!(r[6].focus_at, Some((7.0, 9.0)));
        assert!(r[7].focus_at.is_none());
    }
}
