#!/usr/bin/env bash
# Builds the training and evaluation images from pictures shipped in public packages, so that
# nothing but the registries this project uses (PyPI, Debian, npm) is needed:
#
#   data/train/        photos for training (scikit-image samples, OpenCV samples) + emoji
#   data/eval/photos/  held-out photos for `eval`
#   data/eval/emoji/   held-out emoji for `eval`
#
# Sources and licenses (see each package for the details):
#   - scikit-image 0.24.0 (PyPI wheel), skimage/data: sample photos, public domain / CC0 /
#     permissive as listed in skimage/data/README.txt.
#   - opencv-doc 4.6.0 (Debian bookworm), examples/data: OpenCV's sample images, distributed
#     with OpenCV under its licenses (Apache-2.0 / BSD-3-Clause) for examples and testing.
#   - @twemoji/svg 15.0.0 (npm): Twitter's emoji, CC-BY 4.0 (graphics), rendered at 256 px with
#     rsvg-convert (Debian librsvg2-bin).
#   - gnome-backgrounds 43.1-1 and ukui-wallpapers 20.04.3-1.1 (Debian bookworm): desktop
#     wallpapers, photos and drawings, CC-BY-SA 3.0 (see each package's copyright file);
#     training only. Their SVG wallpapers are rendered at 1024 px wide.
#
# Usage: scripts/fetch-data.sh [DATA_DIR]   (default: data). Re-running rebuilds the folders.
set -euo pipefail

data="${1:-data}"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

need() { command -v "$1" >/dev/null || { echo "fetch-data: $1 is needed ($2)" >&2; exit 1; }; }
need pip "Python's pip"
need npm "Node.js's npm"
need apt-get "Debian's apt"
need dpkg-deb "Debian's dpkg"
if ! command -v rsvg-convert >/dev/null; then
  echo "fetch-data: installing librsvg2-bin for rsvg-convert" >&2
  apt-get install -y --no-install-recommends librsvg2-bin >/dev/null
fi

rm -rf "$data/train" "$data/eval"
mkdir -p "$data/train" "$data/eval/photos" "$data/eval/emoji"

# 1. scikit-image sample photos.
pip download --quiet --no-deps --only-binary=:all: scikit-image==0.24.0 -d "$work/pip"
unzip -q -o -j "$work"/pip/scikit_image-*.whl 'skimage/data/*.png' 'skimage/data/*.jpg' -d "$work/skimage"
for name in astronaut chelsea coffee rocket; do
  cp "$work"/skimage/$name.* "$data/eval/photos/skimage-$(basename "$work"/skimage/$name.*)"
done
for name in motorcycle_left motorcycle_right retina hubble_deep_field ihc color logo immunohistochemistry; do
  for file in "$work"/skimage/$name.*; do
    [ -e "$file" ] && cp "$file" "$data/train/skimage-$(basename "$file")"
  done
done

# 2. OpenCV sample images (colour photos and drawings; calibration boards and text left out).
(cd "$work" && apt-get download opencv-doc=4.6.0+dfsg-12 >/dev/null 2>&1)
dpkg-deb -x "$work"/opencv-doc_*.deb "$work/opencv"
samples="$work/opencv/usr/share/doc/opencv-doc/examples/data"
for name in baboon.jpg fruits.jpg starry_night.jpg butterfly.jpg; do
  cp "$samples/$name" "$data/eval/photos/opencv-$name"
done
for name in aero1.jpg aero3.jpg apple.jpg Blender_Suzanne1.jpg Blender_Suzanne2.jpg building.jpg \
            cards.png chicky_512.png ela_original.jpg graf1.png graf3.png home.jpg leuvenA.jpg \
            leuvenB.jpg lena.jpg messi5.jpg orange.jpg pic2.png pic3.png pic4.png rubberwhale1.png \
            rubberwhale2.png smarties.png squirrel_cls.jpg stuff.jpg basketball1.png basketball2.png \
            opencv-logo.png box_in_scene.png aloeL.jpg board.jpg detect_blob.png gradient.png; do
  [ -e "$samples/$name" ] && cp "$samples/$name" "$data/train/opencv-$name"
done

# 3. Desktop wallpapers (training only).
(cd "$work" && apt-get download gnome-backgrounds=43.1-1 ukui-wallpapers=20.04.3-1.1 >/dev/null 2>&1)
for deb in "$work"/gnome-backgrounds_*.deb "$work"/ukui-wallpapers_*.deb; do
  dpkg-deb -x "$deb" "$work/wallpapers"
done
for file in $(find "$work/wallpapers/usr/share/backgrounds" -type f | sort); do
  name="wallpaper-$(basename "$file")"
  case "$file" in
    *.jpg|*.jpeg|*.png|*.webp) cp "$file" "$data/train/$name" ;;
    *.svg) rsvg-convert -w 1024 "$file" -o "$data/train/${name%.svg}.png" ;;
  esac
done

# 4. Emoji: every 30th of the sorted set for training, a disjoint set for evaluation.
(cd "$work" && npm pack --silent @twemoji/svg@15.0.0 >/dev/null 2>&1)
tar xzf "$work"/twemoji-svg-15.0.0.tgz -C "$work"
index=0
for svg in $(ls "$work"/package/*.svg | sort); do
  name="twemoji-$(basename "$svg" .svg).png"
  if (( index % 30 == 0 )); then
    rsvg-convert -w 256 -h 256 -b white "$svg" -o "$data/train/$name"
  elif (( index % 120 == 6 )); then
    rsvg-convert -w 256 -h 256 -b white "$svg" -o "$data/eval/emoji/$name"
  fi
  index=$((index + 1))
done

echo "fetch-data: $(ls "$data/train" | wc -l) training images, $(ls "$data/eval/photos" | wc -l) photos and $(ls "$data/eval/emoji" | wc -l) emoji for evaluation in $data/"
