"""The expression presets: named muscle contractions (no numpy, so that building the command line,
which offers the preset names, does not load it)."""
from __future__ import annotations

__all__ = ["JAW_KEY", "PRESETS", "PRESET_NAMES"]

JAW_KEY = "jawOpen"

#: contraction presets: base muscle name (both sides when it has _L/_R) -> contraction; "jawOpen"
PRESETS: dict[str, dict[str, float]] = {
    "neutral": {},
    "joy": {"zygomaticMajor": 1.0, "orbicularisOculi": 0.45, "risorius": 0.2, "levatorLabiiSuperioris": 0.15,
            JAW_KEY: 0.08},
    "sadness": {"frontalisInner": 1.0, "corrugator": 0.5, "depressorAnguliOris": 1.0, "mentalis": 0.6},
    "anger": {"corrugator": 1.0, "procerus": 1.0, "orbicularisOculi": 0.5, "orbicularisOris": 0.5,
              "levatorLabiiSuperioris": 0.3},
    "fear": {"frontalisInner": 1.0, "frontalisOuter": 0.5, "corrugator": 0.5, "risorius": 1.0,
             "depressorLabiiInferioris": 0.8, JAW_KEY: 0.2},
    "disgust": {"levatorLabiiAlaeque": 1.0, "levatorLabiiSuperioris": 0.7, "corrugator": 0.4, "procerus": 0.6,
                "orbicularisOculi": 0.35, "depressorAnguliOris": 0.4, "mentalis": 0.4},
    "surprise": {"frontalisInner": 1.0, "frontalisOuter": 1.0, JAW_KEY: 0.4},
    "pursed_lips": {"orbicularisOris": 1.0, "mentalis": 0.3},
}
PRESET_NAMES = tuple(PRESETS)
