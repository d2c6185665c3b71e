//! Keyboard and mouse state per frame, from the window or replayed from a script
//! (`view --script events.txt`), so that a test or a demo drives the viewer through exactly
//! the code a person does.
//!
//! A script has one event per line, `FRAME EVENT ...`, applied before that frame (frames count
//! from 0); `#` starts a comment:
//!
//! | event | meaning |
//! |---|---|
//! | `press KEY` / `release KEY` | a key goes down / up (held in between) |
//! | `tap KEY` | pressed at FRAME, released at FRAME + 1 |
//! | `move X Y` | the cursor moves to window pixel (X, Y) (it starts at (0, 0)) |
//! | `down left\|right` / `up left\|right` | a mouse button goes down / up |
//! | `click X Y` | cursor to (X, Y), left button down at FRAME, up at FRAME + 1 (autofocus) |
//! | `drag DX DY` | left button down at FRAME, cursor moved by (DX, DY) at FRAME + 1, up at FRAME + 2 (look) |
//! | `scroll DY` | the wheel turns by DY (field of view) |
//! | `quit` | the window is closed |
//!
//! Key names are minifb's (`minifb::Key`): `A`-`Z`, `Key0`-`Key9`, `F1`-`F12`, `Up`, `Down`,
//! `Left`, `Right`, `PageUp`, `PageDown`, `Home`, `Space`, `Tab`, `Escape`, `Enter`,
//! `Backspace`, `LeftShift`, `RightShift`, `LeftCtrl`, `RightCtrl`, `Comma`, `Period`,
//! `LeftBracket`, `RightBracket`, `Minus`, `Equal`, `Slash`, `Semicolon`, `Apostrophe`.

use std::collections::BTreeSet;
use std::path::Path;

use anyhow::{Context as _, Result, bail};
use minifb::Key;

/// What the keyboard and the mouse say in one frame.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Input {
    /// Keys down now.
    pub held: BTreeSet<Key>,
    /// Keys that went down this frame (with the window: also auto-repeats of held keys).
    pub pressed: Vec<Key>,
    /// The cursor in window pixels, when it is over the window.
    pub mouse: Option<(f32, f32)>,
    pub left: bool,
    pub right: bool,
    /// Wheel turn this frame (positive: away from the user).
    pub scroll: f32,
    /// The window was closed.
    pub quit: bool,
}

macro_rules! key_names {
    ($($k:ident),* $(,)?) => {
        /// The keys a script may name, by their minifb names.
        const KEYS: &[(&str, Key)] = &[$((stringify!($k), Key::$k)),*];
    };
}

key_names!(
    Key0,
    Key1,
    Key2,
    Key3,
    Key4,
    Key5,
    Key6,
    Key7,
    Key8,
    Key9,
    A,
    B,
    C,
    D,
    E,
    F,
    G,
    H,
    I,
    J,
    K,
    L,
    M,
    N,
    O,
    P,
    Q,
    R,
    S,
    T,
    U,
    V,
    W,
    X,
    Y,
    Z,
    F1,
    F2,
    F3,
    F4,
    F5,
    F6,
    F7,
    F8,
    F9,
    F10,
    F11,
    F12,
    Up,
    Down,
    Left,
    Right,
    PageUp,
    PageDown,
    Home,
    End,
    Space,
    Tab,
    Escape,
    Enter,
    Backspace,
    LeftShift,
    RightShift,
    LeftCtrl,
    RightCtrl,
    Comma,
    Period,
    LeftBracket,
    RightBracket,
    Minus,
    Equal,
    Slash,
    Semicolon,
    Apostrophe,
);

fn key_named(name: &str) -> Option<Key> {
    KEYS.iter().find(|(n, _)| *n == name).map(|(_, k)| *k)
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Action {
    Press(Key),
    Release(Key),
    MoveTo(f32, f32),
    MoveBy(f32, f32),
    Button(bool, bool),
    Scroll(f32),
    Quit,
}

/// A script of input events, replayed frame by frame.
#[derive(Clone, Debug, Default)]
pub struct Script {
    /// (frame, action), in the order written.
    events: Vec<(u32, Action)>,
    state: Input,
}

impl Script {
    pub fn load(path: &Path) -> Result<Script> {
        let text =
            std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
        Script::parse(&text).with_context(|| format!("in the script {}", path.display()))
    }

    pub fn parse(text: &str) -> Result<Script> {
        let mut events = Vec::new();
        for (i, line) in text.lines().enumerate() {
            let line = line.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            parse_line(line, &mut events).with_context(|| format!("line {}: {line:?}", i + 1))?;
        }
        Ok(Script {
            events,
            // The cursor starts at the window's top-left corner.
            state: Input {
                mouse: Some((0.0, 0.0)),
                ..Input::default()
            },
        })
    }

    /// The input of `frame` (frames must be asked for in order, from 0).
    pub fn input(&mut self, frame: u32) -> Input {
        let s = &mut self.state;
        s.pressed.clear();
        s.scroll = 0.0;
        for (_, action) in self.events.iter().filter(|(f, _)| *f == frame) {
            match *action {
                Action::Press(k) => {
                    s.held.insert(k);
                    s.pressed.push(k);
                }
                Action::Release(k) => {
                    s.held.remove(&k);
                }
                Action::MoveTo(x, y) => s.mouse = Some((x, y)),
                Action::MoveBy(dx, dy) => {
                    let (x, y) = s.mouse.unwrap_or((0.0, 0.0));
                    s.mouse = Some((x + dx, y + dy));
                }
                Action::Button(right, down) => {
                    if right {
                        s.right = down;
                    } else {
                        s.left = down;
                    }
                }
                Action::Scroll(d) => s.scroll += d,
                Action::Quit => s.quit = true,
            }
        }
        s.clone()
    }
}

fn parse_line(line: &str, out: &mut Vec<(u32, Action)>) -> Result<()> {
    let words: Vec<&str> = line.split_whitespace().collect();
    let frame: u32 = words[0]
        .parse()
        .with_context(|| format!("{:?} is not a frame number", words[0]))?;
    let args = &words[1..];
    let want = |n: usize| -> Result<()> {
        if args.len() != n + 1 {
            bail!(
                "{} takes {n} value(s)",
                args.first().copied().unwrap_or("an event")
            );
        }
        Ok(())
    };
    let key = |w: &str| {
        key_named(w).with_context(|| {
            format!("no key named {w:?} (minifb names: A-Z, Key0-Key9, Up, LeftShift, ...)")
        })
    };
    let number = |w: &str| -> Result<f32> {
        w.parse::<f32>()
            .ok()
            .filter(|v| v.is_finite())
            .with_context(|| format!("{w:?} is not a number"))
    };
    let button = |w: &str| match w {
        "left" => Ok(false),
        "right" => Ok(true),
        _ => bail!("the mouse buttons are left and right, not {w:?}"),
    };
    match args.first().copied() {
        Some("press") => {
            want(1)?;
            out.push((frame, Action::Press(key(args[1])?)));
        }
        Some("release") => {
            want(1)?;
            out.push((frame, Action::Release(key(args[1])?)));
        }
        Some("tap") => {
            want(1)?;
            let k = key(args[1])?;
            out.push((frame, Action::Press(k)));
            out.push((frame + 1, Action::Release(k)));
        }
        Some("move") => {
            want(2)?;
            out.push((frame, Action::MoveTo(number(args[1])?, number(args[2])?)));
        }
        Some(updown @ ("down" | "up")) => {
            want(1)?;
            out.push((frame, Action::Button(button(args[1])?, updown == "down")));
        }
        Some("click") => {
            want(2)?;
            out.push((frame, Action::MoveTo(number(args[1])?, number(args[2])?)));
            out.push((frame, Action::Button(false, true)));
            out.push((frame + 1, Action::Button(false, false)));
        }
        Some("drag") => {
            want(2)?;
            out.push((frame, Action::Button(false, true)));
            out.push((
                frame + 1,
                Action::MoveBy(number(args[1])?, number(args[2])?),
            ));
            out.push((frame + 2, Action::Button(false, false)));
        }
        Some("scroll") => {
            want(1)?;
            out.push((frame, Action::Scroll(number(args[1])?)));
        }
        Some("quit") => {
            want(0)?;
            out.push((frame, Action::Quit));
        }
        Some(other) => bail!(
            "unknown event {other:?} (press, release, tap, move, down, up, click, drag, scroll, \
             quit)"
        ),
        None => bail!("a frame number needs an event after it"),
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_script_replays_keys_buttons_and_the_cursor_frame_by_frame() {
        let mut s = Script::parse(
            "# look, then walk\n0 move 10 20\n1 drag 5 -3\n2 press W  # held\n4 release W\n\
             5 tap Key2\n6 scroll -1\n7 quit\n",
        )
        .unwrap();
        let f0 = s.input(0);
        assert_eq!(f0.mouse, Some((10.0, 20.0)));
        assert!(!f0.left && f0.held.is_empty());
        assert!(s.input(1).left);
        let f2 = s.input(2);
        assert_eq!(f2.mouse, Some((15.0, 17.0)));
        assert!(f2.left && f2.held.contains(&Key::W) && f2.pressed == [Key::W]);
        let f3 = s.input(3);
        assert!(!f3.left && f3.held.contains(&Key::W) && f3.pressed.is_empty());
        assert!(s.input(4).held.is_empty());
        assert_eq!(s.input(5).pressed, [Key::Key2]);
        let f6 = s.input(6);
        assert!(f6.held.is_empty() && f6.scroll == -1.0);
        assert!(!f6.quit && s.input(7).quit);
    }

    #[test]
    fn script_errors_name_the_line() {
        for (text, says) in [
            ("0 press Wx", "no key named \"Wx\""),
            ("x tap W", "not a frame number"),
            ("0 move 1", "move takes 2"),
            ("3 jump", "unknown event \"jump\""),
            ("1 down middle", "left and right"),
        ] {
            let e = format!(
                "{:#}",
                Script::parse(&format!("# first\n{text}\n")).unwrap_err()
            );
            assert!(e.contains("line 2") && e.contains(says), "{text}: {e}");
        }
    }
}
