#!/usr/bin/env python3
"""GlassNet's `quick` (or `paper`) network re-built in PyTorch, to time one training step on the same CPU as
glassbake's burn/flex training. Only speed is compared: the weights are
random and the data synthetic, as in `cargo run --release -p glassbake-bake --example train_step`.

The layer list mirrors crates/net/src/{blocks,model,config}.rs (quick preset): a 1x1 stem then
3x3 convolutions with leaky ReLU (0.1), stride-2 3x3 down-sampling, 2x2 stride-2 transposed
up-sampling, NeRF positional encoding with 4 frequencies, loss L1 + (1 - SSIM) (11x11 Gaussian,
sigma 1.5), AdamW. Like glassbake's training loop, each step reads its loss back to the host.

    python3 tools/torch-compare/glassnet_step.py [--batch 4] [--crop 32] [--objects 4] [--model glassnet|naive] [--preset quick|paper] [--device cpu|cuda]

It also prints the median no-grad forward pass. tools/torch-compare/compare.sh runs glassbake's
example and this script back to back and prints the ratios.
"""
import argparse
import math
import time

import torch
import torch.nn as nn
import torch.nn.functional as F

# Channels of glassbake_core::layout (OPAQUE_CHANNELS, TRANSPARENT_CHANNELS).
OPAQUE, TRANSPARENT = 17, 22
LEAK = 0.1


class ConvAct(nn.Module):
    def __init__(self, cin, cout, k, stride=1):
        super().__init__()
        self.conv = nn.Conv2d(cin, cout, k, stride=stride, padding=k // 2)

    def forward(self, x):
        return F.leaky_relu(self.conv(x), LEAK)


class DoubleConv(nn.Module):
    def __init__(self, cin, cout, stem=False):
        super().__init__()
        self.a = ConvAct(cin, cout, 1 if stem else 3)
        self.b = ConvAct(cout, cout, 3)

    def forward(self, x):
        return self.b(self.a(x))


class UNet(nn.Module):
    def __init__(self, cin, base, levels, cout):
        super().__init__()
        w = lambda l: base << l
        self.enc = nn.ModuleList([DoubleConv(cin, w(0), stem=True) if l == 0 else DoubleConv(w(l), w(l)) for l in range(levels)])
        self.down = nn.ModuleList([ConvAct(w(l), w(l + 1), 3, stride=2) for l in range(levels - 1)])
        self.up = nn.ModuleList([nn.ConvTranspose2d(w(l + 1), w(l), 2, stride=2) for l in reversed(range(levels - 1))])
        self.dec = nn.ModuleList([DoubleConv(2 * w(l), w(l)) for l in reversed(range(levels - 1))])
        self.head = nn.Conv2d(w(0), cout, 1)

    def forward(self, x):
        skips = []
        for l, block in enumerate(self.enc):
            x = block(x)
            if l < len(self.down):
                skips.append(x)
                x = self.down[l](x)
        for up, block in zip(self.up, self.dec):
            x = block(torch.cat([up(x), skips.pop()], 1))
        return self.head(x)


class PlainCnn(nn.Module):
    def __init__(self, cin, width, layers, cout):
        super().__init__()
        self.layers = nn.Sequential(*[ConvAct(cin if i == 0 else width, width, 1 if i == 0 else 3) for i in range(layers)])
        self.head = nn.Conv2d(width, cout, 1)

    def forward(self, x):
        return self.head(self.layers(x))


class Renderer(nn.Module):
    def __init__(self, cin, width, large, layers, pointwise):
        super().__init__()
        self.body = nn.Sequential(ConvAct(cin, width, large), *[ConvAct(width, width, 3) for _ in range(layers)], *[ConvAct(width, width, 1) for _ in range(pointwise)])
        self.head = nn.Conv2d(width, 3, 1)

    def forward(self, x):
        return self.head(self.body(x))


def encode(x, frequencies):
    parts = [x]
    for k in range(frequencies):
        s = x * (math.pi * (1 << k))
        parts += [torch.sin(s), torch.cos(s)]
    return torch.cat(parts, 1)


# The presets' widths (crates/bake/src/preset.rs): positional-encoding frequencies; F's and B's
# U-Net base width, levels and output channels; h's width, layers and output channels; R's width,
# large kernel, 3x3 layers and 1x1 layers.
PRESETS = {
    "quick": dict(frequencies=4, unet=(12, 3, 12), h=(12, 3, 12), r=(16, 5, 1, 1)),
    "paper": dict(frequencies=6, unet=(32, 4, 32), h=(32, 3, 32), r=(48, 7, 2, 2)),
}


class GlassNet(nn.Module):
    """F and B U-Nets, h a plain CNN summed over the objects, R, at a preset's widths."""

    def __init__(self, model, variables, preset="quick"):
        super().__init__()
        p = PRESETS[preset]
        self.model, self.frequencies, e = model, p["frequencies"], 1 + 2 * p["frequencies"]
        base, levels, sigma = p["unet"]
        width, layers, tau = p["h"]
        self.f = UNet(OPAQUE * e + variables, base, levels, sigma)
        self.h = PlainCnn(TRANSPARENT * e + sigma, width, layers, tau) if model == "glassnet" else None
        self.b = UNet(sigma + tau if model == "glassnet" else sigma, base, levels, sigma)
        self.r = Renderer(sigma + 3, *p["r"])

    def forward(self, gbuffer, transparent, values):
        n, _, h, w = gbuffer.shape
        planes = values[:, :, None, None].expand(n, values.shape[1], h, w)
        sigma = self.f(torch.cat([encode(gbuffer, self.frequencies), planes], 1))
        x = sigma
        if self.h is not None:
            tau = sum(self.h(torch.cat([encode(b, self.frequencies), sigma], 1)) for b in transparent)
            x = torch.cat([sigma, tau], 1)
        return self.r(torch.cat([self.b(x), gbuffer[:, 14:17]], 1)).clamp(0, 1)


def ssim(x, y, window=11, sigma=1.5):
    g = torch.exp(-((torch.arange(window, device=x.device) - window // 2) ** 2) / (2 * sigma * sigma))
    g = g / g.sum()
    c = x.shape[1]
    k = (g[:, None] * g[None, :]).expand(c, 1, window, window).contiguous()
    blur = lambda t: F.conv2d(t, k, groups=c)
    mx, my = blur(x), blur(y)
    sxx, syy, sxy = blur(x * x) - mx * mx, blur(y * y) - my * my, blur(x * y) - mx * my
    c1, c2 = 0.01**2, 0.03**2
    return (((2 * mx * my + c1) * (2 * sxy + c2)) / ((mx * mx + my * my + c1) * (sxx + syy + c2))).mean()


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--batch", type=int, default=4)
    p.add_argument("--crop", type=int, default=32)
    p.add_argument("--objects", type=int, default=4)
    p.add_argument("--variables", type=int, default=4)
    p.add_argument("--model", default="glassnet", choices=["glassnet", "naive"])
    p.add_argument("--preset", default="quick", choices=sorted(PRESETS), help="the network's widths (paper: use --batch 8 --crop 256)")
    p.add_argument("--steps", type=int, default=30)
    p.add_argument("--threads", type=int, default=torch.get_num_threads())
    p.add_argument("--device", default="cpu", help="cpu, or cuda to time the step on an NVIDIA GPU")
    a = p.parse_args()
    device = torch.device(a.device)
    torch.set_num_threads(a.threads)
    torch.manual_seed(0)
    net = GlassNet(a.model, a.variables, a.preset).to(device)
    opt = torch.optim.AdamW(net.parameters(), lr=2e-3, weight_decay=1e-4)
    n, s = a.batch, a.crop
    gbuffer = torch.rand(n, OPAQUE, s, s, device=device)
    transparent = [torch.rand(n, TRANSPARENT, s, s, device=device) for _ in range(a.objects)]
    values = torch.rand(n, a.variables, device=device)
    target = torch.rand(n, 3, s, s, device=device)

    def synchronize():
        if device.type == "cuda":
            torch.cuda.synchronize()

    def step():
        opt.zero_grad(set_to_none=True)
        out = net(gbuffer, transparent, values)
        loss = (out - target).abs().mean() + (1 - ssim(out, target))
        loss.backward()
        opt.step()
        # glassbake reads every step's loss (its NaN guard and log), which waits for the device.
        return loss.item()

    for _ in range(3):
        step()
    synchronize()
    t0 = time.perf_counter()
    for _ in range(a.steps):
        step()
    synchronize()
    per_step = (time.perf_counter() - t0) / a.steps
    # The forward pass alone, without gradients (what a rendered frame costs the network).
    with torch.no_grad():
        times = []
        for i in range(a.steps + 2):
            t0 = time.perf_counter()
            net(gbuffer, transparent, values)
            synchronize()
            if i >= 2:
                times.append(time.perf_counter() - t0)
    forward = sorted(times)[len(times) // 2]
    params = sum(p.numel() for p in net.parameters())
    where = a.device if device.type != "cpu" else f"{a.threads} threads"
    print(f"pytorch {torch.__version__} {a.model} ({a.preset}): {params} parameters, batch {n} x {s} px, {a.objects} objects, "
          f"{where}: {per_step * 1000:.1f} ms/step ({n * s * s / per_step:.0f} px/s), no-grad forward {forward * 1000:.1f} ms")


if __name__ == "__main__":
    main()
