"""Plain PyTorch (1.13) versions of the two big networks of SVD img2vid-xt, for a side-by-side reference benchmark.

* UNetSpatioTemporal: diffusers' UNetSpatioTemporalConditionModel (spec: unet3d.md), optionally with the
  EgoPressureDiff PIFR layers in every spatial transformer block (egopressurediff.md section 6).
* TemporalVAE: diffusers' AutoencoderKLTemporalDecoder (spec: vae.md): the 2-D KL encoder and the temporal decoder.

Parameter names equal diffusers' state-dict keys, so a diffusers-layout safetensors file loads with
load_state_dict(strict=True). The arithmetic follows diffusers' default code path on torch 1.x (explicit attention
scores + softmax + bmm, GEGLU with exact GELU, GroupNorm / LayerNorm from torch), so what the benchmark times is what
diffusers would run on the same PyTorch. Every module computes in the dtype of its parameters (float64 for the
golden check, float32 for timing).
"""

import contextlib
import json
import math
import os

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

# ----------------------------------------------------------------------------------------------------------------
# safetensors without the safetensors package: 8-byte little-endian header length, JSON header, raw data.

_NP_DTYPES = {"F64": np.float64, "F32": np.float32, "F16": np.float16, "I64": np.int64, "I32": np.int32}


def iter_safetensors(path, dtype=torch.float32):
    """(name, tensor) for every tensor of a safetensors file, one at a time; floats are converted to `dtype`."""
    with open(path, "rb") as f:
        n = int.from_bytes(f.read(8), "little")
        header = json.loads(f.read(n))
    raw = np.memmap(path, dtype=np.uint8, mode="r", offset=8 + n)  # mapped, not read: real-size files are GBs
    for name, info in header.items():
        if name == "__metadata__":
            continue
        a, b = info["data_offsets"]
        kind = info["dtype"]
        buf = raw[a:b]
        if kind == "BF16":  # bfloat16 = the upper half of a float32
            arr = (buf.view(np.uint16).astype(np.uint32) << 16).view(np.float32)
        elif kind in _NP_DTYPES:
            arr = buf.view(_NP_DTYPES[kind])
        else:
            raise ValueError(f"{path}: tensor {name} has unsupported dtype {kind}")
        t = torch.from_numpy(np.array(arr).reshape(info["shape"]))  # np.array copies out of the mapping
        yield name, (t.to(dtype) if t.is_floating_point() else t)


def read_safetensors(path, dtype=torch.float32):
    """Every tensor of a safetensors file as a dict of torch tensors; floats are converted to `dtype`."""
    return dict(iter_safetensors(path, dtype))


def component_weight_files(folder, stem="diffusion_pytorch_model"):
    """The safetensors files of a diffusers component folder: STEM.safetensors, or the shards of its index."""
    single = os.path.join(folder, stem + ".safetensors")
    if os.path.exists(single):
        return [single]
    with open(os.path.join(folder, stem + ".safetensors.index.json")) as f:
        return [os.path.join(folder, s) for s in sorted(set(json.load(f)["weight_map"].values()))]


def read_component_weights(folder, stem="diffusion_pytorch_model", dtype=torch.float32):
    out = {}
    for path in component_weight_files(folder, stem):
        out.update(read_safetensors(path, dtype))
    return out


def read_config(folder):
    with open(os.path.join(folder, "config.json")) as f:
        return json.load(f)


# ----------------------------------------------------------------------------------------------------------------
# egopd's synthetic benchmark weights (src/core/synthetic_weights.cpp), reproduced value for value

M64 = (1 << 64) - 1


def fnv1a(name):
    h = 1469598103934665603
    for c in name.encode():
        h = ((h ^ c) * 1099511628211) & M64
    return h


def egopd_synthetic(name, shape, seed):
    """The values of egopd's synthetic_values() (src/core/synthetic_weights.cpp) as float32: splitmix64 streams
    keyed by the FNV-1a hash of the name, restarted every 65536 elements; uniform in +-1/sqrt(fan_in) for
    matrices and kernels, +-0.02 for biases, 1 for norm scales, 0 for mix factors."""
    n = math.prod(shape)
    if name.endswith("mix_factor"):
        return np.zeros(n, np.float32)
    one_d = len(shape) <= 1
    if one_d and name.endswith(".weight"):
        return np.ones(n, np.float32)
    bound = 0.02 if one_d else 1.0 / math.sqrt(max(1, n // shape[0]))
    base = fnv1a(name) ^ ((seed * 0x2545F4914F6CDD1D) & M64)
    c1, c2 = np.uint64(0xBF58476D1CE4E5B9), np.uint64(0x94D049BB133111EB)
    chunk = 1 << 16  # each chunk of 65536 values is one stream starting at state base + chunk start
    steps = np.arange(1, chunk + 1, dtype=np.uint64) * np.uint64(0x9E3779B97F4A7C15)  # k golden-ratio increments
    out = np.empty(n, np.float32)
    z, t = np.empty(chunk, np.uint64), np.empty(chunk, np.float64)
    with np.errstate(over="ignore"):
        for c0 in range(0, n, chunk):
            m = min(chunk, n - c0)
            zz, tt = z[:m], t[:m]
            np.add(steps[:m], np.uint64((base + c0) & M64), out=zz)
            zz ^= zz >> np.uint64(30)
            zz *= c1
            zz ^= zz >> np.uint64(27)
            zz *= c2
            zz ^= zz >> np.uint64(31)
            zz >>= np.uint64(11)
            tt[:] = zz  # u = tt * 2^-53 exactly; then (2u - 1) * bound in double, as egopd computes it
            tt *= 2.0 ** -52
            tt -= 1.0
            tt *= bound
            out[c0:c0 + m] = tt
    return out


def round_to(values, wdtype):
    """float32 values as stored in egopd's F16 / BF16 files (round to nearest even), back in float32."""
    if wdtype == "f16":
        return values.astype(np.float16).astype(np.float32)
    if wdtype == "bf16":
        bits = values.view(np.uint32).astype(np.uint64)
        bits = (bits + 0x7FFF + ((bits >> 16) & 1)) >> 16 << 16
        return bits.astype(np.uint32).view(np.float32)
    return values


# ----------------------------------------------------------------------------------------------------------------
# Shared layers

def sinusoidal_embedding(t, dim):
    """diffusers' get_timestep_embedding with flip_sin_to_cos=True, shift 0: [cos(t f_i), sin(t f_i)]."""
    half = dim // 2
    exponent = -math.log(10000.0) * torch.arange(half, dtype=t.dtype) / half
    arg = t[:, None] * torch.exp(exponent)[None, :]
    return torch.cat([torch.cos(arg), torch.sin(arg)], dim=-1)


class TimestepEmbedding(nn.Module):
    def __init__(self, cin, hidden, cout=None):
        super().__init__()
        self.linear_1 = nn.Linear(cin, hidden)
        self.linear_2 = nn.Linear(hidden, cout or hidden)

    def forward(self, x):
        return self.linear_2(F.silu(self.linear_1(x)))


class Attention(nn.Module):
    """diffusers' Attention with its torch-1.x processor (scores materialised, softmax, bmm).

    Tokens in, tokens out: x [B, L, query_dim], context [B, S, context_dim] (None: self-attention). Heads take
    contiguous channel slices."""

    def __init__(self, query_dim, heads, dim_head, context_dim=None, bias=False):
        super().__init__()
        inner = heads * dim_head
        self.heads = heads
        self.scale = dim_head ** -0.5
        self.to_q = nn.Linear(query_dim, inner, bias=bias)
        self.to_k = nn.Linear(context_dim or query_dim, inner, bias=bias)
        self.to_v = nn.Linear(context_dim or query_dim, inner, bias=bias)
        self.to_out = nn.ModuleList([nn.Linear(inner, query_dim), nn.Dropout(0.0)])  # key to_out.0

    def _split(self, t):  # [B, L, h*d] -> [B*h, L, d]
        b, n, c = t.shape
        return t.reshape(b, n, self.heads, c // self.heads).permute(0, 2, 1, 3).reshape(b * self.heads, n, -1)

    def forward(self, x, context=None):
        ctx = x if context is None else context
        q, k, v = self._split(self.to_q(x)), self._split(self.to_k(ctx)), self._split(self.to_v(ctx))
        # diffusers uses baddbmm(torch.empty(...), beta=0) here; this torch build can let NaNs of the uninitialised
        # buffer through, so the scale goes onto q instead (same work: one L x S product per head).
        scores = torch.bmm(q * self.scale, k.transpose(-1, -2))
        o = torch.bmm(scores.softmax(dim=-1), v)
        bh, n, d = o.shape
        o = o.reshape(bh // self.heads, self.heads, n, d).permute(0, 2, 1, 3).reshape(bh // self.heads, n, -1)
        return self.to_out[0](o)


class MidAttention(Attention):
    """The VAE's single-head mid-block attention: GroupNorm, attention with biases, residual, on [N, C, H, W]."""

    def __init__(self, channels, eps=1e-6):
        super().__init__(channels, 1, channels, bias=True)
        self.group_norm = nn.GroupNorm(32, channels, eps=eps)

    def forward(self, x):
        n, c, h, w = x.shape
        t = self.group_norm(x).reshape(n, c, h * w).transpose(1, 2)
        return super().forward(t).transpose(1, 2).reshape(n, c, h, w) + x


class GEGLU(nn.Module):
    def __init__(self, din, dout):
        super().__init__()
        self.proj = nn.Linear(din, 2 * dout)

    def forward(self, x):
        a, gate = self.proj(x).chunk(2, dim=-1)  # the second half is the gate
        return a * F.gelu(gate)


class FeedForward(nn.Module):
    def __init__(self, dim, dim_out=None, mult=4):
        super().__init__()
        inner = dim * mult
        self.net = nn.ModuleList([GEGLU(dim, inner), nn.Dropout(0.0), nn.Linear(inner, dim_out or dim)])

    def forward(self, x):
        return self.net[2](self.net[0](x))


class ResnetBlock2D(nn.Module):
    """Spatial res-block; temb_channels None = no time embedding (the VAE)."""

    def __init__(self, cin, cout, temb_channels, eps):
        super().__init__()
        self.norm1 = nn.GroupNorm(32, cin, eps=eps)
        self.conv1 = nn.Conv2d(cin, cout, 3, padding=1)
        self.time_emb_proj = nn.Linear(temb_channels, cout) if temb_channels else None
        self.norm2 = nn.GroupNorm(32, cout, eps=eps)
        self.conv2 = nn.Conv2d(cout, cout, 3, padding=1)
        self.conv_shortcut = nn.Conv2d(cin, cout, 1) if cin != cout else None

    def forward(self, x, temb=None):
        h = self.conv1(F.silu(self.norm1(x)))
        if self.time_emb_proj is not None:
            h = h + self.time_emb_proj(F.silu(temb))[:, :, None, None]
        h = self.conv2(F.silu(self.norm2(h)))
        return (x if self.conv_shortcut is None else self.conv_shortcut(x)) + h


class TemporalResnetBlock(nn.Module):
    """Res-block over time on [B, C, F, H, W]: 5-D GroupNorm (statistics over all frames), (3,1,1) convolutions."""

    def __init__(self, channels, temb_channels, eps):
        super().__init__()
        self.norm1 = nn.GroupNorm(32, channels, eps=eps)
        self.conv1 = nn.Conv3d(channels, channels, (3, 1, 1), padding=(1, 0, 0))
        self.time_emb_proj = nn.Linear(temb_channels, channels) if temb_channels else None
        self.norm2 = nn.GroupNorm(32, channels, eps=eps)
        self.conv2 = nn.Conv3d(channels, channels, (3, 1, 1), padding=(1, 0, 0))

    def forward(self, v, temb=None):  # temb [B, F, Ct]
        g = self.conv1(F.silu(self.norm1(v)))
        if self.time_emb_proj is not None:
            g = g + self.time_emb_proj(F.silu(temb)).permute(0, 2, 1)[:, :, :, None, None]
        g = self.conv2(F.silu(self.norm2(g)))
        return v + g


class AlphaBlender(nn.Module):
    """Learned mix of the spatial and temporal branches; image_only_indicator is always 0 here.

    U-Net (learned_with_images): a*spatial + (1-a)*temporal. VAE decoder (switch_spatial_to_temporal_mix): the
    opposite orientation, (1-a)*spatial + a*temporal. a = sigmoid(mix_factor)."""

    def __init__(self, switch=False):
        super().__init__()
        self.mix_factor = nn.Parameter(torch.zeros(1))
        self.switch = switch

    def forward(self, spatial, temporal):
        a = torch.sigmoid(self.mix_factor)
        if self.switch:
            a = 1.0 - a
        return a * spatial + (1.0 - a) * temporal


class SpatioTemporalResBlock(nn.Module):
    def __init__(self, cin, cout, temb_channels, eps, temporal_eps=None, switch=False):
        super().__init__()
        self.spatial_res_block = ResnetBlock2D(cin, cout, temb_channels, eps)
        self.temporal_res_block = TemporalResnetBlock(cout, temb_channels, temporal_eps or eps)
        self.time_mixer = AlphaBlender(switch)

    def forward(self, x, frames, temb=None):
        s = self.spatial_res_block(x, temb)
        n, c, h, w = s.shape
        v = s.reshape(n // frames, frames, c, h, w).permute(0, 2, 1, 3, 4)  # R5: [B, C, F, H, W]
        te = None if temb is None else temb.reshape(n // frames, frames, -1)
        u = self.temporal_res_block(v, te)
        out = self.time_mixer(v, u)
        return out.permute(0, 2, 1, 3, 4).reshape(n, c, h, w)


class Downsample2D(nn.Module):
    """Stride-2 3x3 convolution; padding 0 means the VAE encoder's variant (one zero row/column bottom/right)."""

    def __init__(self, channels, padding=1):
        super().__init__()
        self.padding = padding
        self.conv = nn.Conv2d(channels, channels, 3, stride=2, padding=padding)

    def forward(self, x):
        if self.padding == 0:
            x = F.pad(x, (0, 1, 0, 1))
        return self.conv(x)


class Upsample2D(nn.Module):
    def __init__(self, channels):
        super().__init__()
        self.conv = nn.Conv2d(channels, channels, 3, padding=1)

    def forward(self, x):
        return self.conv(F.interpolate(x, scale_factor=2.0, mode="nearest"))


# ----------------------------------------------------------------------------------------------------------------
# U-Net transformer blocks

class PIFR(nn.Module):
    """EgoPressureDiff text modulation of the prototype cross-attention: z*(1+gamma)+beta, [gamma, beta] =
    Linear(SiLU(attn_text(n, text)))."""

    def __init__(self, dim, heads, text_dim):
        super().__init__()
        self.attn_text = Attention(dim, heads, dim // heads, context_dim=text_dim)
        self.mod = nn.Sequential(nn.SiLU(), nn.Linear(dim, 2 * dim))  # keys mod.1.*

    def forward(self, z_proto, n, text):
        if text is None:  # no text: z_text = 0, so the modulation is the bias alone
            m = self.mod[1].bias.expand(*z_proto.shape[:-1], -1)
        else:
            m = self.mod(self.attn_text(n, text))
        gamma, beta = m.chunk(2, dim=-1)
        return z_proto * (1 + gamma) + beta


class BasicTransformerBlock(nn.Module):
    """Spatial block: self-attention over the tokens of a frame, cross-attention to the image token, GEGLU FF."""

    def __init__(self, dim, heads, context_dim, text_dim=None):
        super().__init__()
        dh = dim // heads
        self.norm1 = nn.LayerNorm(dim)
        self.attn1 = Attention(dim, heads, dh)
        self.norm2 = nn.LayerNorm(dim)
        self.attn2 = Attention(dim, heads, dh, context_dim=context_dim)
        self.norm3 = nn.LayerNorm(dim)
        self.ff = FeedForward(dim)
        self.pifr = PIFR(dim, heads, text_dim) if text_dim else None

    def forward(self, x, ehs, text=None):
        x = self.attn1(self.norm1(x)) + x
        n = self.norm2(x)
        z = self.attn2(n, ehs)
        if self.pifr is not None:
            z = self.pifr(z, n, text)
        x = z + x
        return self.ff(self.norm3(x)) + x


class TemporalBasicTransformerBlock(nn.Module):
    """Temporal block on [B*L, F, C] sequences: FF-in, self-attention over frames, cross-attention, FF."""

    def __init__(self, dim, heads, context_dim):
        super().__init__()
        dh = dim // heads
        self.norm_in = nn.LayerNorm(dim)
        self.ff_in = FeedForward(dim, dim)
        self.norm1 = nn.LayerNorm(dim)
        self.attn1 = Attention(dim, heads, dh)
        self.norm2 = nn.LayerNorm(dim)
        self.attn2 = Attention(dim, heads, dh, context_dim=context_dim)
        self.norm3 = nn.LayerNorm(dim)
        self.ff = FeedForward(dim)

    def forward(self, z, frames, context):
        n, l, c = z.shape
        s = z.reshape(n // frames, frames, l, c).permute(0, 2, 1, 3).reshape(-1, frames, c)  # Seq
        s = self.ff_in(self.norm_in(s)) + s
        s = self.attn1(self.norm1(s)) + s
        s = self.attn2(self.norm2(s), context) + s
        s = self.ff(self.norm3(s)) + s
        return s.reshape(n // frames, l, frames, c).permute(0, 2, 1, 3).reshape(n, l, c)  # Seq^-1


class TransformerSpatioTemporal(nn.Module):
    def __init__(self, dim, heads, context_dim, layers=1, text_dim=None):
        super().__init__()
        self.norm = nn.GroupNorm(32, dim, eps=1e-6)
        self.proj_in = nn.Linear(dim, dim)
        self.transformer_blocks = nn.ModuleList(
            [BasicTransformerBlock(dim, heads, context_dim, text_dim) for _ in range(layers)])
        self.temporal_transformer_blocks = nn.ModuleList(
            [TemporalBasicTransformerBlock(dim, heads, context_dim) for _ in range(layers)])
        self.time_pos_embed = TimestepEmbedding(dim, 4 * dim, dim)
        self.time_mixer = AlphaBlender()
        self.proj_out = nn.Linear(dim, dim)

    def forward(self, x, frames, ehs, text=None):
        n, c, h, w = x.shape
        b = n // frames
        # Temporal cross-attention context: the image tokens of frame 0 of each video, for every spatial position.
        ctx0 = ehs.reshape(b, frames, -1, ehs.shape[-1])[:, 0]
        context = ctx0[:, None].expand(b, h * w, *ctx0.shape[1:]).reshape(b * h * w, -1, ehs.shape[-1])
        z = self.norm(x).permute(0, 2, 3, 1).reshape(n, h * w, c)
        z = self.proj_in(z)
        frame_ids = torch.arange(frames, dtype=x.dtype).repeat(b)
        pe = self.time_pos_embed(sinusoidal_embedding(frame_ids, c))[:, None, :]
        for block, temporal in zip(self.transformer_blocks, self.temporal_transformer_blocks):
            z = block(z, ehs, text)
            zt = temporal(z + pe, frames, context)
            z = self.time_mixer(z, zt)
        z = self.proj_out(z)
        return z.reshape(n, h, w, c).permute(0, 3, 1, 2) + x


# ----------------------------------------------------------------------------------------------------------------
# U-Net blocks and model

class DownBlock(nn.Module):
    """CrossAttnDownBlockSpatioTemporal (with_attention) or DownBlockSpatioTemporal."""

    def __init__(self, cin, cout, temb, layers, with_attention, heads, context_dim, t_layers, add_down, text_dim):
        super().__init__()
        eps = 1e-6 if with_attention else 1e-5  # diffusers' per-block-type res-block eps (unet3d.md section 9)
        self.resnets = nn.ModuleList(
            [SpatioTemporalResBlock(cin if i == 0 else cout, cout, temb, eps) for i in range(layers)])
        self.attentions = nn.ModuleList(
            [TransformerSpatioTemporal(cout, heads, context_dim, t_layers, text_dim) for _ in range(layers)]
            if with_attention else [])
        self.downsamplers = nn.ModuleList([Downsample2D(cout)] if add_down else [])

    def forward(self, x, temb, frames, ehs, text, skips):
        for i, res in enumerate(self.resnets):
            x = res(x, frames, temb)
            if len(self.attentions):
                x = self.attentions[i](x, frames, ehs, text)
            skips.append(x)
        for d in self.downsamplers:
            x = d(x)
            skips.append(x)
        return x


class UpBlock(nn.Module):
    """UpBlockSpatioTemporal or CrossAttnUpBlockSpatioTemporal: each res-block takes [hidden, popped skip]."""

    def __init__(self, cin, cout, prev, temb, layers, with_attention, heads, context_dim, t_layers, add_up, text_dim):
        super().__init__()
        self.resnets = nn.ModuleList()
        for i in range(layers):
            skip = cin if i == layers - 1 else cout
            self.resnets.append(SpatioTemporalResBlock((prev if i == 0 else cout) + skip, cout, temb, 1e-6))
        self.attentions = nn.ModuleList(
            [TransformerSpatioTemporal(cout, heads, context_dim, t_layers, text_dim) for _ in range(layers)]
            if with_attention else [])
        self.upsamplers = nn.ModuleList([Upsample2D(cout)] if add_up else [])

    def forward(self, x, temb, frames, ehs, text, skips):
        for i, res in enumerate(self.resnets):
            x = res(torch.cat([x, skips.pop()], dim=1), frames, temb)
            if len(self.attentions):
                x = self.attentions[i](x, frames, ehs, text)
        for u in self.upsamplers:
            x = u(x)
        return x


class MidBlock(nn.Module):
    def __init__(self, dim, temb, heads, context_dim, t_layers, text_dim):
        super().__init__()
        self.resnets = nn.ModuleList([SpatioTemporalResBlock(dim, dim, temb, 1e-5) for _ in range(2)])
        self.attentions = nn.ModuleList([TransformerSpatioTemporal(dim, heads, context_dim, t_layers, text_dim)])

    def forward(self, x, temb, frames, ehs, text):
        x = self.resnets[0](x, frames, temb)
        x = self.attentions[0](x, frames, ehs, text)
        return self.resnets[1](x, frames, temb)


def _per_block(value, n):
    return list(value) if isinstance(value, (list, tuple)) else [value] * n


class UNetSpatioTemporal(nn.Module):
    """UNetSpatioTemporalConditionModel from a diffusers config dict (+ optional "pifr": {text_dim, enabled})."""

    def __init__(self, cfg):
        super().__init__()
        chans = list(cfg["block_out_channels"])
        nb = len(chans)
        heads = _per_block(cfg["num_attention_heads"], nb)
        ctx = _per_block(cfg["cross_attention_dim"], nb)
        layers = _per_block(cfg["layers_per_block"], nb)
        t_layers = _per_block(cfg.get("transformer_layers_per_block", 1), nb)
        pifr = cfg.get("pifr") or {}
        text_dim = pifr.get("text_dim") if pifr.get("enabled", False) else None
        temb = 4 * chans[0]
        self.c0 = chans[0]
        self.add_dim = cfg["addition_time_embed_dim"]

        self.conv_in = nn.Conv2d(cfg["in_channels"], chans[0], 3, padding=1)
        self.time_embedding = TimestepEmbedding(chans[0], temb)
        self.add_embedding = TimestepEmbedding(cfg["projection_class_embeddings_input_dim"], temb)
        self.down_blocks = nn.ModuleList()
        cout = chans[0]
        for i, kind in enumerate(cfg["down_block_types"]):
            cin, cout = cout, chans[i]
            self.down_blocks.append(DownBlock(cin, cout, temb, layers[i], kind.startswith("CrossAttn"), heads[i],
                                              ctx[i], t_layers[i], i < nb - 1, text_dim))
        self.mid_block = MidBlock(chans[-1], temb, heads[-1], ctx[-1], t_layers[-1], text_dim)
        rc, rh, rctx, rl, rt = (list(reversed(v)) for v in (chans, heads, ctx, layers, t_layers))
        self.up_blocks = nn.ModuleList()
        cout = rc[0]
        for i, kind in enumerate(cfg["up_block_types"]):
            prev, cout, cin = cout, rc[i], rc[min(i + 1, nb - 1)]
            self.up_blocks.append(UpBlock(cin, cout, prev, temb, rl[i] + 1, kind.startswith("CrossAttn"), rh[i],
                                          rctx[i], rt[i], i < nb - 1, text_dim))
        self.conv_norm_out = nn.GroupNorm(32, chans[0], eps=1e-5)
        self.conv_out = nn.Conv2d(chans[0], cfg["out_channels"], 3, padding=1)

    def forward(self, sample, timestep, ehs, added_time_ids, text_tokens=None):
        """sample [B, F, Cin, h, w], timestep scalar or [1] (c_noise), ehs [B, S, D], added_time_ids [B, 3],
        text_tokens [B, 77, T] or None (PIFR no-text mode). Returns the v-prediction [B, F, Cout, h, w]."""
        b, frames = sample.shape[:2]
        dt = sample.dtype
        t = torch.as_tensor(timestep, dtype=dt).reshape(-1).expand(b)
        emb = self.time_embedding(sinusoidal_embedding(t, self.c0))
        aug = sinusoidal_embedding(added_time_ids.to(dt).flatten(), self.add_dim).reshape(b, -1)
        emb = (emb + self.add_embedding(aug)).repeat_interleave(frames, dim=0)
        ehs = ehs.repeat_interleave(frames, dim=0)
        text = None if text_tokens is None else text_tokens.repeat_interleave(frames, dim=0)

        x = self.conv_in(sample.flatten(0, 1))
        skips = [x]
        for blk in self.down_blocks:
            x = blk(x, emb, frames, ehs, text, skips)
        x = self.mid_block(x, emb, frames, ehs, text)
        for blk in self.up_blocks:
            x = blk(x, emb, frames, ehs, text, skips)
        x = self.conv_out(F.silu(self.conv_norm_out(x)))
        return x.reshape(b, frames, *x.shape[1:])


# ----------------------------------------------------------------------------------------------------------------
# Temporal VAE

class EncoderDownBlock(nn.Module):  # DownEncoderBlock2D
    def __init__(self, cin, cout, layers, add_down):
        super().__init__()
        self.resnets = nn.ModuleList([ResnetBlock2D(cin if i == 0 else cout, cout, None, 1e-6) for i in range(layers)])
        self.downsamplers = nn.ModuleList([Downsample2D(cout, padding=0)] if add_down else [])

    def forward(self, x):
        for r in self.resnets:
            x = r(x)
        for d in self.downsamplers:
            x = d(x)
        return x


class EncoderMidBlock(nn.Module):  # UNetMidBlock2D: resnet, attention, resnet
    def __init__(self, dim):
        super().__init__()
        self.resnets = nn.ModuleList([ResnetBlock2D(dim, dim, None, 1e-6) for _ in range(2)])
        self.attentions = nn.ModuleList([MidAttention(dim)])

    def forward(self, x):
        return self.resnets[1](self.attentions[0](self.resnets[0](x)))


class Encoder(nn.Module):
    def __init__(self, cfg):
        super().__init__()
        chans = cfg["block_out_channels"]
        self.conv_in = nn.Conv2d(cfg["in_channels"], chans[0], 3, padding=1)
        self.down_blocks = nn.ModuleList()
        cout = chans[0]
        for i in range(len(cfg["down_block_types"])):
            cin, cout = cout, chans[i]
            self.down_blocks.append(EncoderDownBlock(cin, cout, cfg["layers_per_block"], i < len(chans) - 1))
        self.mid_block = EncoderMidBlock(chans[-1])
        self.conv_norm_out = nn.GroupNorm(32, chans[-1], eps=1e-6)
        self.conv_out = nn.Conv2d(chans[-1], 2 * cfg["latent_channels"], 3, padding=1)

    def forward(self, x):
        x = self.conv_in(x)
        for b in self.down_blocks:
            x = b(x)
        x = self.mid_block(x)
        return self.conv_out(F.silu(self.conv_norm_out(x)))


def _decoder_res(cin, cout):  # spatial eps 1e-6, temporal eps 1e-5, switched mix orientation (vae.md section 4)
    return SpatioTemporalResBlock(cin, cout, None, 1e-6, temporal_eps=1e-5, switch=True)


class DecoderMidBlock(nn.Module):  # MidBlockTemporalDecoder: resnets[0], attention, resnets[1]
    def __init__(self, dim, layers):
        super().__init__()
        self.resnets = nn.ModuleList([_decoder_res(dim, dim) for _ in range(layers)])
        self.attentions = nn.ModuleList([MidAttention(dim)])

    def forward(self, x, frames):
        x = self.resnets[0](x, frames)
        for res, attn in zip(self.resnets[1:], self.attentions):  # diffusers' zip: extra res-blocks never run
            x = res(attn(x), frames)
        return x


class DecoderUpBlock(nn.Module):  # UpBlockTemporalDecoder
    def __init__(self, cin, cout, layers, add_up):
        super().__init__()
        self.resnets = nn.ModuleList([_decoder_res(cin if i == 0 else cout, cout) for i in range(layers)])
        self.upsamplers = nn.ModuleList([Upsample2D(cout)] if add_up else [])

    def forward(self, x, frames):
        for r in self.resnets:
            x = r(x, frames)
        for u in self.upsamplers:
            x = u(x)
        return x


class TemporalDecoder(nn.Module):
    def __init__(self, cfg):
        super().__init__()
        chans = cfg["block_out_channels"]
        rc = list(reversed(chans))
        lpb = cfg["layers_per_block"]
        self.conv_in = nn.Conv2d(cfg["latent_channels"], chans[-1], 3, padding=1)
        self.mid_block = DecoderMidBlock(chans[-1], lpb)
        self.up_blocks = nn.ModuleList()
        cout = rc[0]
        for i in range(len(chans)):
            cin, cout = cout, rc[i]
            self.up_blocks.append(DecoderUpBlock(cin, cout, lpb + 1, i < len(chans) - 1))
        self.conv_norm_out = nn.GroupNorm(32, chans[0], eps=1e-6)
        self.conv_out = nn.Conv2d(chans[0], cfg["out_channels"], 3, padding=1)
        self.time_conv_out = nn.Conv3d(cfg["out_channels"], cfg["out_channels"], (3, 1, 1), padding=(1, 0, 0))

    def forward(self, z, frames):
        x = self.mid_block(self.conv_in(z), frames)
        for b in self.up_blocks:
            x = b(x, frames)
        x = self.conv_out(F.silu(self.conv_norm_out(x)))
        n, c, h, w = x.shape
        v = x.reshape(n // frames, frames, c, h, w).permute(0, 2, 1, 3, 4)
        return self.time_conv_out(v).permute(0, 2, 1, 3, 4).reshape(n, c, h, w)


class TemporalVAE(nn.Module):
    """AutoencoderKLTemporalDecoder from a diffusers config dict (no post_quant_conv in this model)."""

    def __init__(self, cfg):
        super().__init__()
        self.latent_channels = cfg["latent_channels"]
        self.scaling_factor = cfg.get("scaling_factor", 0.18215)
        self.encoder = Encoder(cfg)
        self.quant_conv = nn.Conv2d(2 * cfg["latent_channels"], 2 * cfg["latent_channels"], 1)
        self.decoder = TemporalDecoder(cfg)

    def encode(self, images):
        """images [N, 3, H, W] in [-1, 1] -> (mean, logvar clamped to [-30, 20]), each [N, 4, H/8, W/8]."""
        moments = self.quant_conv(self.encoder(images))
        mean, logvar = moments.split(self.latent_channels, dim=1)
        return mean, logvar.clamp(-30.0, 20.0)

    def decode(self, z, num_frames):
        """diffusers' decode(z, num_frames): the rows are B videos of num_frames frames each; no scaling."""
        return self.decoder(z, num_frames)

    def decode_latents(self, latents, num_frames, chunk=None):
        """The pipeline's decode_latents: z / scaling_factor (as a multiplication by the reciprocal), then chunks of
        `chunk` rows (default num_frames), each decoded as one sequence of its own rows (vae.md section 5)."""
        z = (1.0 / self.scaling_factor) * latents
        chunk = chunk or num_frames
        return torch.cat([self.decode(z[i:i + chunk], z[i:i + chunk].shape[0]) for i in range(0, z.shape[0], chunk)])


@contextlib.contextmanager
def no_init():
    """Builds modules without torch's default random init (every parameter is overwritten afterwards); at real
    size that init alone takes longer than a forward pass."""
    saved = nn.Linear.reset_parameters, nn.modules.conv._ConvNd.reset_parameters
    nn.Linear.reset_parameters = nn.modules.conv._ConvNd.reset_parameters = lambda self: None
    try:
        yield
    finally:
        nn.Linear.reset_parameters, nn.modules.conv._ConvNd.reset_parameters = saved


def build_model(kind, cfg):
    with no_init():
        return UNetSpatioTemporal(cfg) if kind == "unet" else TemporalVAE(cfg)


def _drop_disabled_pifr(kind, cfg, names):
    """With PIFR absent or disabled in the config its keys are ignored (egopressurediff.md section 6.5)."""
    if kind == "unet" and not (cfg.get("pifr") or {}).get("enabled", False):
        return {n for n in names if ".pifr." not in n}
    return set(names)


def load_model(kind, folder, dtype=torch.float32):
    """A UNetSpatioTemporal ("unet") or TemporalVAE ("vae") from a diffusers component folder, through
    load_state_dict(strict=True). Holds the file's tensors and the model at once: for small models."""
    cfg = read_config(folder)
    model = build_model(kind, cfg).to(dtype).eval()
    weights = read_component_weights(folder, dtype=dtype)
    keep = _drop_disabled_pifr(kind, cfg, weights)
    model.load_state_dict({k: v for k, v in weights.items() if k in keep}, strict=True)
    return model


def load_model_streaming(kind, folder, dtype=torch.float32):
    """As load_model, with the same strict key and shape checks, but copying one tensor at a time, so a real-size
    model never exists twice in memory (which would distort the benchmark's peak RSS)."""
    cfg = read_config(folder)
    model = build_model(kind, cfg).to(dtype).eval()
    params = model.state_dict()
    seen = set()
    with torch.no_grad():
        for path in component_weight_files(folder):
            for name, t in iter_safetensors(path, dtype):
                if name not in _drop_disabled_pifr(kind, cfg, [name]):
                    continue
                if name not in params:
                    raise KeyError(f"{folder}: unexpected key {name}")
                if tuple(t.shape) != tuple(params[name].shape):
                    raise ValueError(f"{folder}: {name} has shape {list(t.shape)}, the model {list(params[name].shape)}")
                params[name].copy_(t)
                seen.add(name)
    missing = sorted(set(params) - seen)
    if missing:
        raise KeyError(f"{folder}: {len(missing)} missing keys, e.g. {missing[:3]}")
    return model
