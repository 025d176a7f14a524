#!/usr/bin/env python3
"""Tiles images into one PNG contact sheet, or joins them into a looping GIF.

  python3 scenes/contact_sheet.py sheet OUT.png COLUMNS IMAGE...
  python3 scenes/contact_sheet.py gif OUT.gif MS_PER_FRAME IMAGE...

Needs Pillow (apt-get install python3-pil); only for the README's pictures.
"""
import sys

from PIL import Image


def main():
    mode, out, arg, paths = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4:]
    images = [Image.open(p).convert("RGB") for p in paths]
    if mode == "gif":
        images[0].save(out, save_all=True, append_images=images[1:], duration=arg, loop=0)
        return
    w, h = images[0].size
    rows = (len(images) + arg - 1) // arg
    sheet = Image.new("RGB", (w * arg, h * rows), "white")
    for i, im in enumerate(images):
        sheet.paste(im, ((i % arg) * w, (i // arg) * h))
    sheet.save(out)


if __name__ == "__main__":
    main()
