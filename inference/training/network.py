"""The inverse-graphics encoder (PyTorch; training and export only, never at inference).

After Kips et al. 2021 ("Deep graphics encoder for real-time video makeup synthesis from example"):
a fully convolutional net of strided conv blocks, global average pooling and a small head with a
sigmoid over the six normalised Table 1 parameters. It outputs the logits too, so that inference
can flag estimates pressed against the edge of the parameter range.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import torch
from torch import nn


@dataclass(frozen=True)
class EncoderConfig:
    width: int = 16        # channels of the first block; each block doubles them
    blocks: int = 4        # strided blocks: the input is downsampled by 2**blocks
    input_size: int = 48   # side of the square input in pixels

    def to_dict(self) -> dict:
        return asdict(self)


def _block(c_in: int, c_out: int) -> nn.Sequential:
    return nn.Sequential(
        nn.Conv2d(c_in, c_out, 3, stride=2, padding=1, bias=False), nn.BatchNorm2d(c_out), nn.ReLU(inplace=True),
        nn.Conv2d(c_out, c_out, 3, padding=1, bias=False), nn.BatchNorm2d(c_out), nn.ReLU(inplace=True),
    )


class HairEncoder(nn.Module):
    def __init__(self, config: EncoderConfig = EncoderConfig()) -> None:
        super().__init__()
        self.config = config
        widths = [config.width * 2**i for i in range(config.blocks)]
        layers, c_in = [], 3
        for w in widths:
            layers.append(_block(c_in, w))
            c_in = w
        self.features = nn.Sequential(*layers)
        self.head = nn.Sequential(nn.Linear(c_in, 64), nn.ReLU(inplace=True), nn.Linear(64, 6))

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``x``: (N, 3, S, S) sRGB in [-0.5, 0.5]. Returns (parameters in [0, 1], logits)."""
        logits = self.head(self.features(x).mean(dim=(2, 3)))
        return torch.sigmoid(logits), logits


def parameter_count(model: nn.Module) -> int:
    return sum(p.numel() for p in model.parameters())
