"""Level-0 heights of a terrain database (docs/formats.md), read tile by tile from its index:
for the scripts and tests that check or plan flights over a database without loading it."""
import struct


class LevelZero:
    def __init__(self, path):
        self.f = open(path, "rb")
        h = self.f.read(256)
        self.tile, self.width, self.height = struct.unpack_from("<III", h, 12)
        self.sx, self.sy, self.scale, self.offset = struct.unpack_from("<dddd", h, 32)
        self.index_off, = struct.unpack_from("<Q", h, 88)
        self.tiles_x = (self.width - 1 + self.tile - 1) // self.tile
        self.tiles_y = (self.height - 1 + self.tile - 1) // self.tile
        self.cache = {}

    def _tile(self, tx, ty):
        if (tx, ty) not in self.cache:
            self.f.seek(self.index_off + (ty * self.tiles_x + tx) * 24)
            off, stored = struct.unpack("<QI", self.f.read(12))
            self.f.seek(off)
            t = self.f.read(stored)
            tw, th = struct.unpack_from("<II", t, 16)
            self.cache[(tx, ty)] = (tw, struct.unpack_from(f"<{tw * th}H", t, 24))
        return self.cache[(tx, ty)]

    def sample(self, i, j):
        """Height in metres of sample (i, j), clamped to the map."""
        i = min(max(i, 0), self.width - 1)
        j = min(max(j, 0), self.height - 1)
        tx = min(i // self.tile, self.tiles_x - 1)
        ty = min(j // self.tile, self.tiles_y - 1)
        tw, hs = self._tile(tx, ty)
        return hs[(j - ty * self.tile) * tw + (i - tx * self.tile)] * self.scale + self.offset

    def nearest(self, x, y):
        """Height of the sample nearest world (x, y)."""
        return self.sample(int(round(x / self.sx)), int(round(y / self.sy)))

    def surface(self, x, y):
        """The map's bilinear surface at world (x, y), inside the map."""
        gx, gy = x / self.sx, y / self.sy
        i, j = int(gx), int(gy)
        fx, fy = gx - i, gy - j
        return ((self.sample(i, j) * (1 - fx) + self.sample(i + 1, j) * fx) * (1 - fy) +
                (self.sample(i, j + 1) * (1 - fx) + self.sample(i + 1, j + 1) * fx) * fy)
