//! Putting a frame on the window: the frame's RGBA bytes (already tone
//! mapped, overlays drawn) are uploaded as a texture and drawn over the
//! window's surface with one full-screen triangle. Every driver, CPU or GPU,
//! ends in the same bytes, so the window needs nothing of the GPU but a
//! surface, and runs on software Vulkan (lavapipe) where there is no GPU.

use std::sync::Arc;

use winit::window::Window;

use super::WindowError;

const SHADER: &str = r"
@group(0) @binding(0) var frame: texture_2d<f32>;
@group(0) @binding(1) var pick: sampler;

struct Out {
    @builtin(position) position: vec4<f32>,
    @location(0) uv: vec2<f32>,
};

@vertex
fn vs(@builtin(vertex_index) i: u32) -> Out {
    // One triangle covering the screen: (0,0), (2,0), (0,2) in uv.
    let uv = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    var out: Out;
    out.position = vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
    out.uv = vec2<f32>(uv.x, 1.0 - uv.y);
    return out;
}

@fragment
fn fs(in: Out) -> @location(0) vec4<f32> {
    return textureSample(frame, pick, in.uv);
}
";

/// The window's surface, the device it is drawn with, and the frame texture.
pub struct Presenter {
    surface: wgpu::Surface<'static>,
    device: wgpu::Device,
    queue: wgpu::Queue,
    config: wgpu::SurfaceConfiguration,
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
    sampler: wgpu::Sampler,
    /// The frame texture and its bind group, remade when the size changes.
    frame: Option<(wgpu::Texture, wgpu::BindGroup, u32, u32)>,
    /// The texture's format: sRGB where the surface's is, so that the
    /// bytes, already sRGB-encoded, reach the screen unchanged.
    texture_format: wgpu::TextureFormat,
    /// The adapter in words.
    pub adapter: String,
}

/// How the window's surface is configured for `caps` at `size`: a plain
/// 8-bit format first (the bytes are already what the screen shows),
/// mailbox presentation where offered; and the format of the frame texture
/// that matches it. `adapter` names the GPU in the error.
fn surface_config(
    caps: &wgpu::SurfaceCapabilities,
    size: winit::dpi::PhysicalSize<u32>,
    adapter: &str,
) -> Result<(wgpu::SurfaceConfiguration, wgpu::TextureFormat), WindowError> {
    let format = [
        wgpu::TextureFormat::Bgra8Unorm,
        wgpu::TextureFormat::Rgba8Unorm,
        wgpu::TextureFormat::Bgra8UnormSrgb,
        wgpu::TextureFormat::Rgba8UnormSrgb,
    ]
    .into_iter()
    .find(|f| caps.formats.contains(f))
    .or_else(|| caps.formats.first().copied())
    .ok_or_else(|| WindowError::Gpu(format!("{adapter} cannot present to this window")))?;
    let texture_format = if format.is_srgb() {
        wgpu::TextureFormat::Rgba8UnormSrgb
    } else {
        wgpu::TextureFormat::Rgba8Unorm
    };
    let present_mode = if caps.present_modes.contains(&wgpu::PresentMode::Mailbox) {
        wgpu::PresentMode::Mailbox
    } else {
        wgpu::PresentMode::Fifo
    };
    let config = wgpu::SurfaceConfiguration {
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
        format,
        color_space: wgpu::SurfaceColorSpace::Auto,
        width: size.width.max(1),
        height: size.height.max(1),
        desired_maximum_frame_latency: 2,
        present_mode,
        alpha_mode: caps
            .alpha_modes
            .first()
            .copied()
            .unwrap_or(wgpu::CompositeAlphaMode::Auto),
        view_formats: vec![],
    };
    Ok((config, texture_format))
}

/// The pipeline that draws the frame texture over the whole window, its
/// bind group layout (texture, sampler) and its nearest-neighbour sampler.
fn frame_pipeline(
    device: &wgpu::Device,
    format: wgpu::TextureFormat,
) -> (wgpu::RenderPipeline, wgpu::BindGroupLayout, wgpu::Sampler) {
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("window frame"),
        source: wgpu::ShaderSource::Wgsl(SHADER.into()),
    });
    let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("window frame"),
        entries: &[
            wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Float { filterable: true },
                    view_dimension: wgpu::TextureViewDimension::D2,
                    multisampled: false,
                },
                count: None,
            },
            wgpu::BindGroupLayoutEntry {
                binding: 1,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                count: None,
            },
        ],
    });
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("window frame"),
        bind_group_layouts: &[Some(&layout)],
        immediate_size: 0,
    });
    let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("window frame"),
        layout: Some(&pipeline_layout),
        vertex: wgpu::VertexState {
            module: &module,
            entry_point: Some("vs"),
            compilation_options: Default::default(),
            buffers: &[],
        },
        primitive: wgpu::PrimitiveState::default(),
        depth_stencil: None,
        multisample: Default::default(),
        fragment: Some(wgpu::FragmentState {
            module: &module,
            entry_point: Some("fs"),
            compilation_options: Default::default(),
            targets: &[Some(format.into())],
        }),
        multiview_mask: None,
        cache: None,
    });
    let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
        label: Some("window frame"),
        mag_filter: wgpu::FilterMode::Nearest,
        min_filter: wgpu::FilterMode::Nearest,
        ..Default::default()
    });
    (pipeline, layout, sampler)
}

impl Presenter {
    /// Opens a device that can present to `window` (from `instance`).
    pub fn new(instance: &wgpu::Instance, window: Arc<Window>) -> Result<Presenter, WindowError> {
        let size = window.inner_size();
        let surface = instance
            .create_surface(window)
            .map_err(|e| WindowError::Gpu(format!("creating the window surface: {e}")))?;
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: false,
            compatible_surface: Some(&surface),
            ..Default::default()
        }))
        .map_err(|e| {
            WindowError::Gpu(format!(
                "no GPU adapter can draw into the window ({e}); on Linux without a GPU, install Mesa's \
                 software Vulkan (apt-get install mesa-vulkan-drivers)"
            ))
        })?;
        let info = adapter.get_info();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("holodeck window"),
            ..Default::default()
        }))
        .map_err(|e| WindowError::Gpu(format!("opening {}: {e}", info.name)))?;
        let caps = surface.get_capabilities(&adapter);
        let (config, texture_format) = surface_config(&caps, size, &info.name)?;
        surface.configure(&device, &config);
        let (pipeline, layout, sampler) = frame_pipeline(&device, config.format);
        Ok(Presenter {
            surface,
            device,
            queue,
            config,
            pipeline,
            layout,
            sampler,
            frame: None,
            texture_format,
            adapter: format!("{} ({:?})", info.name, info.backend),
        })
    }

    /// Follows a window resize.
    pub fn resize(&mut self, width: u32, height: u32) {
        if width == 0 || height == 0 {
            return;
        }
        self.config.width = width;
        self.config.height = height;
        self.surface.configure(&self.device, &self.config);
    }

    /// Shows a frame of `width` x `height` RGBA bytes, top row first
    /// (stretched if the window has another size by now).
    pub fn present(&mut self, rgba: &[u8], width: u32, height: u32) -> Result<(), WindowError> {
        if rgba.len() != width as usize * height as usize * 4 || width == 0 || height == 0 {
            return Err(WindowError::Gpu(format!(
                "a {width} x {height} frame of {} bytes",
                rgba.len()
            )));
        }
        if !matches!(self.frame, Some((_, _, w, h)) if w == width && h == height) {
            let texture = self.device.create_texture(&wgpu::TextureDescriptor {
                label: Some("window frame"),
                size: wgpu::Extent3d {
                    width,
                    height,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: self.texture_format,
                usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
                view_formats: &[],
            });
            let view = texture.create_view(&Default::default());
            let group = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("window frame"),
                layout: &self.layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: wgpu::BindingResource::TextureView(&view),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: wgpu::BindingResource::Sampler(&self.sampler),
                    },
                ],
            });
            self.frame = Some((texture, group, width, height));
        }
        let Some((texture, group, _, _)) = &self.frame else {
            return Ok(());
        };
        self.queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            rgba,
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(width * 4),
                rows_per_image: Some(height),
            },
            wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
        );
        let surface_texture = match self.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(t) | wgpu::CurrentSurfaceTexture::Suboptimal(t) => t,
            wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
                // Resized or lost under us: configure again and skip this frame.
                self.surface.configure(&self.device, &self.config);
                return Ok(());
            }
            // Hidden or busy: nothing to draw into now.
            _ => return Ok(()),
        };
        let target = surface_texture.texture.create_view(&Default::default());
        let mut encoder = self.device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("window frame"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &target,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: None,
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, group, &[]);
            pass.draw(0..3, 0..1);
        }
        self.queue.submit([encoder.finish()]);
        self.queue.present(surface_texture);
        Ok(())
    }
}
