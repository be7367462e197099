//! The window mode: a winit window (X11 or Wayland) presenting with the runtime's own device.
//! Each frame is one command buffer: the crowd's compute passes (`Batch::record`; four, as it
//! has no tangents), the draw straight from the crowd's output buffers (`Renderer::record`),
//! and a blit to the swapchain image (`swapchain.rs`), with two frames in flight (the crowd's frame slots). The
//! animation plays at 30 frames per second of wall time.

use crate::swapchain::{Frame, Presenter, FRAMES_IN_FLIGHT};
use crate::{Args, Error, Show};
use raw_window_handle::{HasDisplayHandle, HasWindowHandle};
use rrskin::vk::ash::{self, vk};
use rrskin::vk::{Context, ContextDesc, PassTimings};
use rrskin::Model;
use rrskin_render::{grid_scene, GridScene, Renderer, CROWD_BACKGROUND};
use std::time::{Duration, Instant};
use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::{ElementState, KeyEvent, WindowEvent};
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::keyboard::{Key, NamedKey};
use winit::window::{Window, WindowId};

const ANIMATION_FPS: f64 = 30.0;
const TITLE_EVERY: Duration = Duration::from_millis(500);

pub fn run(args: &Args, model: &Model) -> Result<(), Error> {
    let event_loop = EventLoop::new().map_err(|e| {
        // winit prefixes its own source location ("os error at …/winit-…/mod.rs:765: "): keep
        // the reason, and say what works without a display.
        let text = e.to_string();
        let reason = text
            .rsplit_once(".rs:")
            .and_then(|(_, rest)| rest.split_once(": "))
            .map_or(text.as_str(), |(_, reason)| reason);
        format!("cannot open a window: {reason}\n  without a display, render offscreen: --headless [--out crowd.png]")
    })?;
    let display = event_loop.display_handle()?.as_raw();
    let instance_extensions = ash_window::enumerate_required_extensions(display)?
        .iter()
        // SAFETY: ash-window returns pointers to static NUL-terminated extension names.
        .map(|&name| unsafe { std::ffi::CStr::from_ptr(name) })
        .collect();
    let ctx = Context::new(&ContextDesc {
        validation: args.validate,
        instance_extensions,
        device_extensions: vec![ash::khr::swapchain::NAME],
        ..Default::default()
    })?;
    let mut app = App {
        show: Show::new(ctx, model, args)?,
        frames: args.frames,
        shown: None,
        error: None,
    };
    event_loop.run_app(&mut app)?;
    if let Some(shown) = &app.shown {
        let seconds = shown.opened.elapsed().as_secs_f64();
        println!(
            "presented {} frames in {seconds:.1} s ({:.1} frames/s, window {}x{})",
            shown.presented,
            shown.presented as f64 / seconds,
            shown.presenter.extent.width,
            shown.presenter.extent.height
        );
    }
    // The presenter waits for the frames in flight before the crowds go; then the last frame of
    // each slot has completed, and its timings are kept too.
    drop(app.shown.take());
    for slot in 0..FRAMES_IN_FLIGHT {
        app.show.sample(slot)?;
    }
    match app.error.take() {
        Some(e) => Err(e),
        None => app.show.finish(),
    }
}

struct App {
    show: Show,
    /// Stop after this many presented frames (for tests and measurements).
    frames: Option<usize>,
    shown: Option<Shown>,
    error: Option<Error>,
}

/// The window and what draws into it. Field order is drop order: the presenter (surface and
/// swapchain) goes before the window it was made for.
struct Shown {
    presenter: Presenter,
    renderer: Option<Renderer>,
    scene: GridScene,
    stale: bool,
    presented: usize,
    clock: Clock,
    title_at: Instant,
    opened: Instant,
    window: Window,
}

/// Animation time that can be paused.
struct Clock {
    start: Instant,
    paused_at: Option<Instant>,
}

impl Clock {
    fn frame(&self) -> usize {
        let now = self.paused_at.unwrap_or_else(Instant::now);
        ((now - self.start).as_secs_f64() * ANIMATION_FPS) as usize
    }

    fn toggle(&mut self) {
        match self.paused_at.take() {
            Some(at) => self.start += at.elapsed(),
            None => self.paused_at = Some(Instant::now()),
        }
    }
}

impl App {
    fn open(&mut self, event_loop: &ActiveEventLoop) -> Result<Shown, Error> {
        let attributes = Window::default_attributes()
            .with_title("rrskin crowd")
            .with_inner_size(PhysicalSize::new(1280, 720));
        let window = event_loop.create_window(attributes)?;
        let ctx = &self.show.ctx;
        // SAFETY: the window outlives the surface (`Shown`'s field order); the instance has the
        // display's surface extensions (`run`).
        let surface = unsafe {
            ash_window::create_surface(
                ctx.entry(),
                ctx.instance(),
                window.display_handle()?.as_raw(),
                window.window_handle()?.as_raw(),
                None,
            )
        }?;
        let size = window.inner_size();
        let presenter = Presenter::new(ctx, surface, [size.width, size.height])?;
        let mut shown = Shown {
            presenter,
            renderer: None,
            scene: grid_scene(&self.show.shown().model, 1, 1.0),
            stale: false,
            presented: 0,
            clock: Clock {
                start: Instant::now(),
                paused_at: None,
            },
            title_at: Instant::now(),
            opened: Instant::now(),
            window,
        };
        self.fit(&mut shown)?;
        Ok(shown)
    }

    /// Sizes the offscreen target and the camera to the swapchain.
    fn fit(&self, shown: &mut Shown) -> Result<(), Error> {
        let vk::Extent2D { width, height } = shown.presenter.extent;
        shown.renderer = None;
        if width > 0 && height > 0 {
            shown.renderer = Some(Renderer::new(&self.show.ctx, width, height)?);
            let model = &self.show.shown().model;
            let characters = self.show.shown().crowd.character_count();
            shown.scene = grid_scene(model, characters, width as f32 / height as f32);
        }
        Ok(())
    }

    fn redraw(&mut self, shown: &mut Shown) -> Result<(), Error> {
        if shown.stale {
            let size = shown.window.inner_size();
            shown.presenter.resize([size.width, size.height])?;
            self.fit(shown)?;
            shown.stale = false;
        }
        let Some(renderer) = &shown.renderer else {
            return Ok(()); // minimised
        };
        let show = &mut self.show;
        let (scene, time) = (&shown.scene, shown.clock.frame());
        let frame = shown.presenter.frame(
            renderer.color_image(),
            vk::Extent2D {
                width: renderer.width(),
                height: renderer.height(),
            },
            |cmd, slot| {
                // The slot's last frame completed: keep its timings, pose it anew.
                show.sample(slot)?;
                show.pose(slot, time)?;
                let crowd = &show.methods[show.current].crowd;
                show.batch.record(cmd, slot, &[crowd])?;
                renderer.record(cmd, &scene.camera, &scene.draws(crowd), CROWD_BACKGROUND)?;
                Ok(())
            },
        )?;
        match frame {
            Frame::Presented { stale } => {
                shown.stale = stale;
                shown.presented += 1;
            }
            Frame::Skipped => shown.stale = true,
        }
        if shown.title_at.elapsed() >= TITLE_EVERY {
            shown.title_at = Instant::now();
            shown.window.set_title(&self.title());
        }
        Ok(())
    }

    /// The median pass times of the last 30 frames of the shown method.
    fn title(&self) -> String {
        let m = self.show.shown();
        let recent = &m.samples[m.samples.len().saturating_sub(30)..];
        let Some((t, _)) = PassTimings::median(recent) else {
            return format!("rrskin crowd: {}", m.name);
        };
        format!(
            "rrskin crowd: {} x {} vertices, {} (L switches) | GPU ms: predictors {:.2}, C1/C2 {:.2}, skinning {:.2}, normals {:.2}, total {:.2}",
            m.crowd.character_count(),
            m.model.vertex_count(),
            m.name,
            t.predict_ms,
            t.product_ms,
            t.skin_ms,
            t.normals_ms,
            t.total_ms()
        )
    }

    fn fail(&mut self, event_loop: &ActiveEventLoop, e: Error) {
        self.error.get_or_insert(e);
        event_loop.exit();
    }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.shown.is_none() && self.error.is_none() {
            match self.open(event_loop) {
                Ok(shown) => {
                    shown.window.request_redraw();
                    self.shown = Some(shown);
                }
                Err(e) => self.fail(event_loop, e),
            }
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _: WindowId, event: WindowEvent) {
        let Some(mut shown) = self.shown.take() else {
            return;
        };
        match event {
            WindowEvent::CloseRequested => event_loop.exit(),
            WindowEvent::Resized(_) => shown.stale = true,
            WindowEvent::KeyboardInput {
                event:
                    KeyEvent {
                        logical_key,
                        state: ElementState::Pressed,
                        repeat: false,
                        ..
                    },
                ..
            } => match logical_key.as_ref() {
                Key::Named(NamedKey::Escape) => event_loop.exit(),
                Key::Named(NamedKey::Space) => shown.clock.toggle(),
                Key::Character(c) if c.eq_ignore_ascii_case("l") => {
                    self.show.switch();
                    shown.window.set_title(&self.title());
                }
                _ => {}
            },
            WindowEvent::RedrawRequested => match self.redraw(&mut shown) {
                Ok(()) if self.frames.is_some_and(|n| shown.presented >= n) => event_loop.exit(),
                Ok(()) => shown.window.request_redraw(),
                Err(e) => self.fail(event_loop, e),
            },
            _ => {}
        }
        self.shown = Some(shown);
    }
}
