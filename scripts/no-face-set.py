#!/usr/bin/env python3
"""The finder's hard no-face set: title cards, printed text, logos and patterned fabric.

Writes tests/data/no-face/<kind>-<nn>.jpg (640x480, JPEG quality 82) and a README listing them.
Every picture is drawn here from a fixed seed, with the DejaVu and Liberation fonts of Debian's
fonts-dejavu-core and fonts-liberation packages (their licences place no restriction on
rendered output), so the set is the project's own and is committed; tests read the JPEGs and do
not need Python. Re-run only to change the set:

    python3 -m venv /tmp/nf && /tmp/nf/bin/pip install pillow numpy
    /tmp/nf/bin/python scripts/no-face-set.py

Why these kinds: the face finder once reported faces inside the lettering of a title card
(issue 20). Lettering, logos built of rings and bars, and regular textures are what a face
detector's dark-blob/light-band features most often fire on.
"""

import math
import os
import random

import numpy as np
from PIL import Image, ImageDraw, ImageFilter, ImageFont

W, H = 640, 480
ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
OUT = os.path.join(ROOT, "tests", "data", "no-face")
FONT_DIRS = ["/usr/share/fonts/truetype/dejavu", "/usr/share/fonts/truetype/liberation"]
FONTS = sorted(
    os.path.join(d, f) for d in FONT_DIRS if os.path.isdir(d) for f in os.listdir(d) if f.endswith(".ttf")
)
WORDS = (
    "the of and a to in is you that it he was for on are as with his they at be this have from or one had by "
    "word but not what all were we when your can said there use an each which she do how their if will up other "
    "about out many then them these so some her would make like him into time has look two more write go see "
    "number no way could people my than first water been call who oil its now find long down day did get come "
    "made may part over new sound take only little work know place year live me back give most very after thing "
    "our just name good sentence man think say great where help through much before line right too mean old any "
    "same tell boy follow came want show also around form three small set put end does another well large must "
    "big even such because turn here why ask went men read need land different home us move try kind hand picture "
    "again change off play spell air away animal house point page letter mother answer found study still learn"
).split()
TITLES = [
    "CHAPTER ONE", "THE END", "Part Two", "INTERVIEW", "facemimic", "Episode 4", "LOOKING GLASS", "GOOD MOOD",
    "BOOK CLUB", "OPEN 24 HOURS", "Q & A", "Intermission", "COMING SOON", "ZOO", "Session 3: Results", "BOOM",
]
LOGO_WORDS = ["LOOK", "BOOK", "OO", "GOOGOL", "MOON", "ODEON", "COOP", "OXO", "808", "ZOOM", "NOOK", "POOL"]


def font(rng, size, bold=None):
    choices = [f for f in FONTS if (bold is None) or (("Bold" in f) == bold)]
    return ImageFont.truetype(rng.choice(choices), size)


def text_size(draw, text, fnt):
    x0, y0, x1, y1 = draw.textbbox((0, 0), text, font=fnt)
    return x1 - x0, y1 - y0, x0, y0


def gradient(rng, c0, c1, vertical=True):
    t = np.linspace(0, 1, H if vertical else W, dtype=np.float32)
    t = t[:, None] if vertical else t[None, :]
    img = np.zeros((H, W, 3), np.float32)
    for k in range(3):
        img[..., k] = c0[k] + (c1[k] - c0[k]) * t
    return Image.fromarray(img.clip(0, 255).astype(np.uint8))


def title_card(rng, i):
    dark = rng.random() < 0.7
    c0 = [rng.randrange(0, 50) for _ in range(3)] if dark else [rng.randrange(170, 255) for _ in range(3)]
    c1 = [min(255, c + rng.randrange(0, 60)) for c in c0] if dark else [max(0, c - rng.randrange(0, 60)) for c in c0]
    img = gradient(rng, c0, c1, rng.random() < 0.5)
    d = ImageDraw.Draw(img)
    fg = (rng.randrange(200, 256),) * 3 if dark else (rng.randrange(0, 60),) * 3
    if rng.random() < 0.4:
        fg = tuple(rng.randrange(120, 256) for _ in range(3)) if dark else tuple(rng.randrange(0, 120) for _ in range(3))
    title = TITLES[i % len(TITLES)]
    size = rng.choice([36, 48, 64, 80, 96, 120])
    fnt = font(rng, size, bold=rng.random() < 0.6)
    while True:
        tw, th, ox, oy = text_size(d, title, fnt)
        if tw < W - 40 or size < 20:
            break
        size = int(size * 0.85)
        fnt = font(rng, size)
    y = (H - th) // 2 + rng.randrange(-80, 60)
    d.text(((W - tw) // 2 - ox, y - oy), title, font=fnt, fill=fg)
    if rng.random() < 0.7:
        sub = " ".join(rng.choice(WORDS) for _ in range(rng.randrange(2, 6))).title()
        sf = font(rng, max(14, size // 3), bold=False)
        sw, sh, sox, soy = text_size(d, sub, sf)
        d.text(((W - sw) // 2 - sox, y + th + size // 3 - soy), sub, font=sf, fill=fg)
    if rng.random() < 0.4:
        m = rng.randrange(12, 40)
        d.rectangle([m, m, W - m, H - m], outline=fg, width=rng.choice([1, 2, 4]))
    if rng.random() < 0.3:  # a video's softness
        img = img.filter(ImageFilter.GaussianBlur(rng.choice([0.6, 1.0, 1.5])))
    return img


def printed_text(rng, i):
    paper = tuple(rng.randrange(215, 250) - k * rng.randrange(0, 6) for k in range(3))
    img = Image.new("RGB", (W, H), paper)
    d = ImageDraw.Draw(img)
    ink = (rng.randrange(0, 50),) * 3
    kind = i % 4
    if kind == 0:  # paragraphs, one column
        size = rng.choice([11, 13, 15, 18, 22])
        fnt = font(rng, size, bold=False)
        y = rng.randrange(10, 30)
        while y < H - size:
            line = " ".join(rng.choice(WORDS) for _ in range(40))
            d.text((24, y), line, font=fnt, fill=ink)
            y += int(size * rng.choice([1.3, 1.5, 1.8]))
            if rng.random() < 0.12:
                y += size
    elif kind == 1:  # newspaper: a headline and columns
        hf = font(rng, rng.choice([34, 42, 52]), bold=True)
        d.text((20, 12), " ".join(rng.choice(WORDS) for _ in range(4)).upper(), font=hf, fill=ink)
        cols = rng.choice([2, 3, 4])
        cw = (W - 40) // cols
        fnt = font(rng, rng.choice([10, 12, 14]), bold=False)
        for c in range(cols):
            y = 80
            while y < H - 14:
                line = " ".join(rng.choice(WORDS) for _ in range(12))
                d.text((20 + c * cw, y), line, font=fnt, fill=ink)
                y += 16
            d.rectangle([20 + c * cw - 4 + cw, 80, 20 + c * cw + cw, H], fill=paper)
            d.line([16 + c * cw + cw, 80, 16 + c * cw + cw, H - 10], fill=ink, width=1)
    elif kind == 2:  # a table of numbers
        fnt = font(rng, rng.choice([12, 14, 16]), bold=False)
        rows, cols = rng.randrange(12, 22), rng.randrange(4, 8)
        rh, cw = (H - 40) // rows, (W - 40) // cols
        for r in range(rows + 1):
            d.line([20, 20 + r * rh, 20 + cols * cw, 20 + r * rh], fill=ink, width=1)
        for c in range(cols + 1):
            d.line([20 + c * cw, 20, 20 + c * cw, 20 + rows * rh], fill=ink, width=1)
        for r in range(rows):
            for c in range(cols):
                v = f"{rng.uniform(0, 999):.{rng.choice([0, 1, 2])}f}"
                d.text((26 + c * cw, 22 + r * rh), v, font=fnt, fill=ink)
    else:  # code listing, monospace, on a dark or light screen
        dark = rng.random() < 0.5
        img = Image.new("RGB", (W, H), (30, 30, 36) if dark else paper)
        d = ImageDraw.Draw(img)
        fnt = ImageFont.truetype(rng.choice([f for f in FONTS if "Mono" in f]), rng.choice([12, 14, 16]))
        y = 8
        indent = 0
        while y < H - 16:
            indent = max(0, min(6, indent + rng.choice([-1, 0, 0, 1])))
            line = "    " * indent + " ".join(rng.choice(WORDS + ["{", "}", "(", ")", "=", "0", "if", "fn"]) for _ in range(rng.randrange(2, 9)))
            col = tuple(rng.randrange(120, 240) for _ in range(3)) if dark else ink
            d.text((10, y), line, font=fnt, fill=col)
            y += fnt.size + 4
    if rng.random() < 0.5:  # a photographed page: turned a little, shaded
        img = img.rotate(rng.uniform(-6, 6), resample=Image.BICUBIC, fillcolor=(rng.randrange(40, 120),) * 3)
        a = np.asarray(img).astype(np.float32)
        yy, xx = np.mgrid[0:H, 0:W]
        shade = 0.8 + 0.2 * np.cos((xx / W - rng.random()) * math.pi) * np.cos((yy / H - rng.random()) * math.pi)
        img = Image.fromarray((a * shade[..., None]).clip(0, 255).astype(np.uint8))
    return img


def logo(rng, i):
    bg = tuple(rng.randrange(0, 256) for _ in range(3))
    img = Image.new("RGB", (W, H), bg)
    d = ImageDraw.Draw(img)
    fg = tuple((c + 128 + rng.randrange(-40, 40)) % 256 for c in bg)
    fg2 = tuple(rng.randrange(0, 256) for _ in range(3))
    cx, cy = W // 2 + rng.randrange(-60, 60), H // 2 + rng.randrange(-40, 40)
    r = rng.randrange(50, 150)
    kind = i % 6
    if kind == 0:  # a word mark full of O's
        word = LOGO_WORDS[i % len(LOGO_WORDS)]
        fnt = font(rng, rng.choice([72, 96, 130]), bold=True)
        tw, th, ox, oy = text_size(d, word, fnt)
        while tw > W - 30:
            fnt = font(rng, int(fnt.size * 0.8), bold=True)
            tw, th, ox, oy = text_size(d, word, fnt)
        d.text((cx - tw // 2 - ox, cy - th // 2 - oy), word, font=fnt, fill=fg)
        if rng.random() < 0.5:
            d.line([cx - tw // 2, cy + th // 2 + 14, cx + tw // 2, cy + th // 2 + 14], fill=fg2, width=6)
    elif kind == 1:  # rings (olympic-like, audi-like)
        n = rng.choice([2, 3, 4, 5])
        rr = rng.randrange(30, 60)
        for k in range(n):
            x = cx + (k - (n - 1) / 2) * rr * 1.5
            y = cy + (rr * 0.5 if (k % 2 and rng.random() < 0.5) else 0)
            d.ellipse([x - rr, y - rr, x + rr, y + rr], outline=fg if k % 2 else fg2, width=rng.choice([6, 10, 14]))
    elif kind == 2:  # a letter in a circle or a shield
        d.ellipse([cx - r, cy - r, cx + r, cy + r], fill=fg)
        fnt = font(rng, int(r * 1.2), bold=True)
        ch = rng.choice("ABDGHMOQRSW&")
        tw, th, ox, oy = text_size(d, ch, fnt)
        d.text((cx - tw // 2 - ox, cy - th // 2 - oy), ch, font=fnt, fill=bg)
    elif kind == 3:  # a star or polygon badge with a banner
        n = rng.choice([5, 6, 8, 12])
        pts = []
        for k in range(2 * n):
            a = math.pi * k / n - math.pi / 2
            rad = r if k % 2 == 0 else r * rng.uniform(0.45, 0.8)
            pts.append((cx + rad * math.cos(a), cy + rad * math.sin(a)))
        d.polygon(pts, fill=fg)
        d.rectangle([cx - r * 1.2, cy - 18, cx + r * 1.2, cy + 18], fill=fg2)
        fnt = font(rng, 24, bold=True)
        word = rng.choice(LOGO_WORDS)
        tw, th, ox, oy = text_size(d, word, fnt)
        d.text((cx - tw // 2 - ox, cy - th // 2 - oy), word, font=fnt, fill=bg)
    elif kind == 4:  # overlapping circles and chevrons
        for k in range(rng.randrange(3, 7)):
            rr = rng.randrange(20, 90)
            x, y = cx + rng.randrange(-120, 120), cy + rng.randrange(-80, 80)
            d.ellipse([x - rr, y - rr, x + rr, y + rr], fill=tuple(rng.randrange(0, 256) for _ in range(3)))
        for k in range(3):
            y = cy + 90 + k * 18
            d.line([cx - 60, y, cx, y + 14, cx + 60, y], fill=fg, width=7)
    else:  # a tiled pattern of small marks (a brand's monogram print)
        fnt = font(rng, rng.choice([20, 28, 36]), bold=True)
        mono = rng.choice(["OO", "GG", "CC", "LV", "OXO", "◯"]) if False else rng.choice(["OO", "GG", "CC", "LV", "OXO"])
        step = fnt.size * 2
        for y in range(-step, H + step, step):
            for x in range(-step, W + step, step):
                off = step // 2 if (y // step) % 2 else 0
                d.text((x + off, y), mono, font=fnt, fill=fg)
    if rng.random() < 0.4:
        img = img.filter(ImageFilter.GaussianBlur(0.8))
    return img


def fabric(rng, i):
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float32)
    ang = rng.uniform(-0.4, 0.4)
    u = xx * math.cos(ang) + yy * math.sin(ang)
    v = -xx * math.sin(ang) + yy * math.cos(ang)
    c1 = np.array([rng.randrange(0, 256) for _ in range(3)], np.float32)
    c2 = np.array([rng.randrange(0, 256) for _ in range(3)], np.float32)
    c3 = np.array([rng.randrange(0, 256) for _ in range(3)], np.float32)
    kind = i % 7
    p = rng.uniform(16, 60)
    if kind == 0:  # tartan: crossing bands of two widths
        a = ((u % p) < p * 0.35).astype(np.float32) + 0.5 * ((u % (p / 3)) < p / 12)
        b = ((v % p) < p * 0.35).astype(np.float32) + 0.5 * ((v % (p / 3)) < p / 12)
        t = (a + b) / 3
        img = c1 * (1 - t[..., None]) + c2 * t[..., None]
    elif kind == 1:  # gingham
        a = ((u % p) < p / 2).astype(np.float32)
        b = ((v % p) < p / 2).astype(np.float32)
        t = (a + b) / 2
        img = c1 * (1 - t[..., None]) + np.array([250, 250, 250], np.float32) * (1 - t[..., None]) * 0 + c2 * t[..., None]
        img = np.where(t[..., None] == 0, np.array([245, 245, 240], np.float32), img)
    elif kind == 2:  # houndstooth-like: a checker with diagonal teeth
        q = p / 2
        cu, cv = np.floor(u / q), np.floor(v / q)
        fu, fv = (u % q) / q, (v % q) / q
        base = (cu + cv) % 2
        tooth = ((fu + fv) < 1) & ((cu % 2) == 0)
        t = np.where(tooth, 1 - base, base)
        img = c1 * (1 - t[..., None]) + np.array([240, 236, 228], np.float32) * t[..., None]
    elif kind == 3:  # polka dots
        q = p
        fu = (u % q) - q / 2
        fv = (v % q) - q / 2
        r = rng.uniform(0.15, 0.35) * q
        t = (fu * fu + fv * fv < r * r).astype(np.float32)
        img = c1 * (1 - t[..., None]) + c2 * t[..., None]
    elif kind == 4:  # stripes of three colours
        s = (u % (3 * p)) / p
        img = np.where((s < 1)[..., None], c1, np.where((s < 2)[..., None], c2, c3))
    elif kind == 5:  # knit / twill: small repeating ribs
        t = 0.5 + 0.5 * np.sin(2 * math.pi * (u / 6 + 0.5 * np.abs(np.sin(2 * math.pi * v / 10))))
        img = c1 * (0.55 + 0.45 * t[..., None])
    else:  # leopard / floral blobs: rings around random centres
        img = np.tile(c1, (H, W, 1))
        im = Image.fromarray(img.astype(np.uint8))
        d = ImageDraw.Draw(im)
        for _ in range(rng.randrange(60, 160)):
            x, y = rng.randrange(0, W), rng.randrange(0, H)
            a, b = rng.uniform(6, 22), rng.uniform(5, 18)
            d.ellipse([x - a, y - b, x + a, y + b], outline=tuple(int(c) for c in c2), width=rng.choice([3, 5]))
            d.ellipse([x - a / 2, y - b / 2, x + a / 2, y + b / 2], fill=tuple(int(c) for c in c3))
        img = np.asarray(im).astype(np.float32)
    # Folds and light: a slow shading, then a fine weave noise.
    nrng = np.random.default_rng(1000 + i)
    fold = 0.75 + 0.25 * np.sin(2 * math.pi * (xx * rng.uniform(0.002, 0.008) + yy * rng.uniform(0.001, 0.006)) + rng.uniform(0, 6))
    img = img * fold[..., None] + nrng.normal(0, 6, (H, W, 1))
    out = Image.fromarray(img.clip(0, 255).astype(np.uint8))
    return out.filter(ImageFilter.GaussianBlur(0.7))


def main():
    os.makedirs(OUT, exist_ok=True)
    for f in os.listdir(OUT):
        if f.endswith(".jpg"):
            os.remove(os.path.join(OUT, f))
    kinds = [("title", title_card, 16), ("text", printed_text, 12), ("logo", logo, 12), ("fabric", fabric, 14)]
    rows = []
    for name, fn, n in kinds:
        for i in range(n):
            rng = random.Random(f"{name}-{i}")
            img = fn(rng, i)
            path = os.path.join(OUT, f"{name}-{i:02}.jpg")
            img.convert("RGB").save(path, quality=82, optimize=True)
            rows.append((name, path))
    with open(os.path.join(OUT, "README.md"), "w") as f:
        f.write(
            "# The hard no-face set\n\n"
            "Title cards, printed text, logos and patterned fabric (640x480 JPEG), drawn by\n"
            "`scripts/no-face-set.py` from fixed seeds: the project's own pictures, no face in any\n"
            "of them. `tests/integration/no_face.rs` asserts that the face finder reports no face on any.\n\n"
            "| kind | files |\n|---|---|\n"
        )
        for name, _, n in kinds:
            f.write(f"| {name} | {name}-00.jpg .. {name}-{n - 1:02}.jpg |\n")
    print(f"{len(rows)} images in {os.path.relpath(OUT, ROOT)}")


if __name__ == "__main__":
    main()
