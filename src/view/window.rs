//! The window: minifb (a software framebuffer with keyboard and mouse). Chosen because it
//! needs nothing at build time beyond the crate (on Linux it loads libX11 and libXcursor when
//! the window opens, so the binary builds and its tests run on machines without X headers), it
//! runs the same under Xvfb as on a desktop X server (or XWayland), Windows and macOS, and the
//! viewer only ever shows one image a frame, which a framebuffer does without a GPU context
//! (winit + softbuffer would do the same with more code; an OpenGL window like the thesis's
//! would not open under a bare Xvfb).

use anyhow::{Result, anyhow, bail};
use minifb::{KeyRepeat, MouseButton, MouseMode, Window, WindowOptions};

use super::input::Input;

/// Fails with what to do when there is no display to open a window on.
pub fn check_display() -> Result<()> {
    #[cfg(all(unix, not(target_os = "macos")))]
    {
        let set = |v: &str| std::env::var_os(v).is_some_and(|d| !d.is_empty());
        if !set("DISPLAY") {
            let wayland = if set("WAYLAND_DISPLAY") {
                " (WAYLAND_DISPLAY is set, but the viewer opens X11 windows: enable XWayland, \
                 which sets DISPLAY)"
            } else {
                ""
            };
            bail!(
                "noisefree view needs a display, and DISPLAY is not set{wayland}. Run it in a \
                 desktop session, or start a virtual X server and point DISPLAY at it: \
                 `Xvfb :99 -screen 0 1280x1024x24 & DISPLAY=:99 noisefree view ...` (or \
                 `xvfb-run noisefree view ...`; Debian package xvfb)"
            );
        }
    }
    Ok(())
}

/// A window showing one `width × height` image a frame.
pub struct ViewerWindow {
    window: Window,
    /// What the window shows, 0RGB.
    pub pixels: Vec<u32>,
    pub width: usize,
    pub height: usize,
}

impl ViewerWindow {
    pub fn open(title: &str, width: u32, height: u32) -> Result<ViewerWindow> {
        check_display()?;
        let (w, h) = (width as usize, height as usize);
        let mut window = Window::new(title, w, h, WindowOptions::default()).map_err(|e| {
            anyhow!(
                "cannot open a window on DISPLAY={}: {e}. Is an X server running there? \
                 Without a desktop, start one with `Xvfb :99 -screen 0 1280x1024x24 &` and set \
                 DISPLAY=:99",
                std::env::var("DISPLAY").unwrap_or_default()
            )
        })?;
        // The frame rate is the renderer's; minifb would otherwise sleep to cap it.
        window.set_target_fps(0);
        Ok(ViewerWindow {
            window,
            pixels: vec![0; w * h],
            width: w,
            height: h,
        })
    }

    /// Fills the window's pixels from 8-bit sRGB bytes (3 a pixel).
    pub fn set_rgb8(&mut self, rgb8: &[u8]) {
        for (p, c) in self.pixels.iter_mut().zip(rgb8.chunks_exact(3)) {
            *p = (c[0] as u32) << 16 | (c[1] as u32) << 8 | c[2] as u32;
        }
    }

    /// Shows the pixels and reads the input that arrived meanwhile.
    pub fn present(&mut self) -> Result<()> {
        self.window
            .update_with_buffer(&self.pixels, self.width, self.height)
            .map_err(|e| anyhow!("updating the window: {e}"))
    }

    /// The keyboard and mouse as of the last [`ViewerWindow::present`].
    pub fn input(&self) -> Input {
        let w = &self.window;
        Input {
            held: w.get_keys().into_iter().collect(),
            pressed: w.get_keys_pressed(KeyRepeat::Yes),
            mouse: w.get_mouse_pos(MouseMode::Discard),
            left: w.get_mouse_down(MouseButton::Left),
            right: w.get_mouse_down(MouseButton::Right),
            scroll: w.get_scroll_wheel().map_or(0.0, |s| s.1),
            quit: !w.is_open(),
        }
    }

    pub fn is_open(&self) -> bool {
        self.window.is_open()
    }

    /// The pixels as 8-bit RGB bytes (for a screenshot of the window, heads-up line included).
    pub fn rgb8(&self) -> Vec<u8> {
        self.pixels
            .iter()
            .flat_map(|p| [(p >> 16) as u8, (p >> 8) as u8, *p as u8])
            .collect()
    }
}
