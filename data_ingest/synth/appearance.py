"""How a drive looks: colours of the environment, light of the daytime, and the weather.

A :class:`Look` turns a primitive's base colour and its distance from the camera into the
colour drawn (:func:`shade`: headlights at night, wet sheen, fog, contrast), and
:class:`ImageEffects` adds what is not a primitive: rain streaks, snow flakes and sensor
noise, from tiles made once per drive so every frame costs a few array additions.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import cv2
import numpy as np

WHITE_PAINT, YELLOW_PAINT = (230.0, 230.0, 230.0), (40.0, 185.0, 225.0)
# BGR base colours of the surfaces beside and on the road, per environment.
PALETTES = {
    "highway": {"asphalt": (88, 88, 92), "grass": (70, 125, 85), "terrain": (75, 120, 95), "sidewalk": (160, 162, 165),
                "curb": (165, 165, 165)},
    "urban": {"asphalt": (100, 100, 104), "grass": (70, 125, 85), "terrain": (120, 122, 126),
              "sidewalk": (165, 168, 172), "curb": (185, 185, 185)},
    "rural": {"asphalt": (80, 84, 88), "grass": (60, 130, 90), "terrain": (70, 120, 90), "sidewalk": (160, 162, 165),
              "curb": (165, 165, 165)},
}
SNOW = (235.0, 235.0, 238.0)
# (sky at the horizon, sky at the top) per weather, by day; night skies are dark.
DAY_SKIES = {"sun": ((235, 215, 195), (205, 140, 80)), "rain": ((175, 175, 170), (120, 120, 115)),
             "fog": ((200, 200, 198), (200, 200, 198)), "snow": ((215, 215, 215), (175, 175, 180))}
NIGHT_SKY = ((45, 32, 28), (15, 8, 5))
NIGHT_FOG = (50, 50, 52)
VISIBILITY_M = {"sun": (2500.0, 4000.0), "rain": (250.0, 450.0), "fog": (40.0, 120.0), "snow": (200.0, 400.0)}
NIGHT_AMBIENT = 0.12
HEADLIGHT_RANGE_M = 25.0  # distance at which the headlights' light has fallen to half
HEADLIGHT_SPREAD = 0.45  # tan of the beam's half width


@dataclass(frozen=True)
class Look:
    """Everything about colour and atmosphere of one drive."""

    daytime: str
    weather: str
    palette: dict[str, np.ndarray]  # material -> BGR
    white: np.ndarray
    yellow: np.ndarray
    sky_horizon: np.ndarray
    sky_top: np.ndarray
    visibility_m: float  # meteorological: contrast is down to 5 % at this distance
    ambient: float  # light without headlights: 1 by day
    wet: float  # strength of the road's sky reflection
    contrast: float
    snow_cover: float  # fraction of the painted lines under snow
    noise_sigma: float  # sensor noise, grey levels


def make_look(environment: str, daytime: str, weather: str, rng: np.random.Generator) -> Look:
    palette = {name: np.array(color, float) for name, color in PALETTES[environment].items()}
    white, yellow = np.array(WHITE_PAINT), np.array(YELLOW_PAINT)
    if weather == "snow":
        palette.update({name: np.array(SNOW) for name in ("grass", "terrain", "sidewalk", "curb")})
        palette["asphalt"] = palette["asphalt"] * 0.4 + np.array(SNOW) * 0.6 * 0.8
    if weather == "rain":
        palette["asphalt"] = palette["asphalt"] * 0.7
    horizon, top = NIGHT_SKY if daytime == "night" else DAY_SKIES[weather]
    if daytime == "night" and weather == "fog":
        horizon = top = NIGHT_FOG
    night = daytime == "night"
    return Look(
        daytime, weather, palette, white, yellow, np.array(horizon, float), np.array(top, float),
        visibility_m=float(rng.uniform(*VISIBILITY_M[weather])),
        ambient=NIGHT_AMBIENT if night else 1.0,
        wet={"rain": 0.45, "snow": 0.1}.get(weather, 0.0),
        contrast={"rain": 0.75, "snow": 0.85, "fog": 0.9}.get(weather, 1.0),
        snow_cover=0.45 if weather == "snow" else 0.0,
        noise_sigma=5.0 if night else 2.5,
    )


def without_noise(look: Look) -> Look:
    return replace(look, noise_sigma=0.0)


def shade(look: Look, color: np.ndarray, distance: np.ndarray, bearing: np.ndarray,
          emissive: np.ndarray, reflective: np.ndarray) -> np.ndarray:
    """Colours (P, 3) drawn for base colours (P, 3) of primitives at ``distance`` (P,) metres.

    bearing: (P,) lateral tan of the direction from the camera (x / z), for the headlight beam.
    emissive: (P,) lights, which the dark does not dim. reflective: (P,) the road surface,
    which mirrors the sky when wet.
    """
    color = np.asarray(color, float)
    if look.ambient < 1:
        beam = np.exp(-((bearing / HEADLIGHT_SPREAD) ** 2)) / (1 + (distance / HEADLIGHT_RANGE_M) ** 2)
        light = np.where(emissive, 1.0, np.minimum(look.ambient + beam, 1.0))
        color = color * light[:, None]
    if look.wet > 0:
        sheen = (look.wet * (1 - np.exp(-distance / 60.0)) * reflective)[:, None]
        color = color * (1 - sheen) + look.sky_horizon * look.ambient * sheen
    # Fog, haze: Koschmieder's law, 5 % contrast left at the visibility distance. Lights pierce it more.
    fog = 1 - np.exp(-3.0 * distance / look.visibility_m)
    fog = (np.where(emissive, 0.5, 1.0) * fog)[:, None]
    color = color * (1 - fog) + look.sky_horizon * fog
    return fade_contrast(look, color)


def fade_contrast(look: Look, color: np.ndarray) -> np.ndarray:
    """Low-contrast weather pulls colours (..., 3) towards grey."""
    grey = look.sky_horizon.mean() * 0.8
    return grey + (color - grey) * look.contrast


def sky_rows(look: Look, height: int) -> np.ndarray:
    """(4 * height, 3) uint8 sky colours; row j is (2 * height - j) pixels above the horizon."""
    above = 2 * height - np.arange(4 * height)
    t = np.clip(above / (0.8 * height), 0.0, 1.0)[:, None] ** 0.7
    colors = look.sky_horizon * (1 - t) + look.sky_top * t
    return np.clip(fade_contrast(look, colors), 0, 255).astype(np.uint8)


class ImageEffects:
    """Rain streaks, snow flakes and sensor noise for images of one size, drawn from ``rng`` once."""

    TILES = 4

    def __init__(self, look: Look, width: int, height: int, rng: np.random.Generator) -> None:
        self.look = look
        self._layers = [self._weather_layer(look.weather, width, height, rng) for _ in range(self.TILES)]
        tiles = self.TILES if look.noise_sigma > 0 else 0
        noise = [rng.normal(0.0, look.noise_sigma, (height, width, 3)) for _ in range(tiles)]
        # Signed noise as two saturating uint8 additions is far cheaper than int16 arithmetic.
        self._noise = [(np.clip(n, 0, 255).astype(np.uint8), np.clip(-n, 0, 255).astype(np.uint8)) for n in noise]

    @staticmethod
    def _weather_layer(weather: str, width: int, height: int, rng: np.random.Generator) -> np.ndarray | None:
        layer = np.zeros((height, width, 3), np.uint8)
        scale = max(width / 480, 0.5)
        if weather == "rain":
            for _ in range(width * height // 900):
                x, y = rng.uniform(0, width), rng.uniform(0, height)
                length = rng.uniform(8, 22) * scale
                cv2.line(layer, (int(x), int(y)), (int(x - 0.25 * length), int(y + length)),
                         (60, 60, 60), max(1, int(scale)), cv2.LINE_AA)
            return layer
        if weather == "snow":
            for _ in range(width * height // 700):
                x, y = rng.uniform(0, width), rng.uniform(0, height)
                level = int(rng.uniform(120, 220))
                cv2.circle(layer, (int(x), int(y)), int(rng.integers(1, 3) * scale), (level,) * 3, -1, cv2.LINE_AA)
            return layer
        return None

    def apply(self, image: np.ndarray, frame_index: int) -> np.ndarray:
        """``image`` (H, W, 3) uint8 with the frame's weather layer and noise added (in place where possible)."""
        layer = self._layers[frame_index % self.TILES]
        if layer is not None:
            if self.look.weather == "rain":
                image = cv2.GaussianBlur(image, (3, 3), 0)
            cv2.add(image, layer, dst=image)
        if self.look.noise_sigma > 0:
            positive, negative = self._noise[(frame_index * 3 + 1) % self.TILES]
            cv2.add(image, positive, dst=image)
            cv2.subtract(image, negative, dst=image)
        return image
