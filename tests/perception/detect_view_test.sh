#!/usr/bin/env bash
# markloop-detect --view: one PNG per image, the bird's-eye view at twice
# its size, a truncated image and one declaring a huge size refused while
# the others run, and a clear refusal when the directory cannot be made.
set -euo pipefail
detect=$1 sim=$2 work=$3
rm -rf "$work" && mkdir -p "$work"
source "$(dirname "$0")/../cli_check.sh"

"$sim" training-set --out "$work/set" --seed 9002 --frames 2 >/dev/null 2>&1
images=("$work"/set/images/*.png)
check "view written" 0 "" -- "$detect" --camera "$work/set/camera.yaml" --view "$work/view" "${images[@]}"
# PNG header: width and height, big-endian, at bytes 16..23. The simulator's
# camera views 346 x 316 pixels (the region and its guard band).
for image in "${images[@]}"; do
  view="$work/view/$(basename "${image%.png}").png"
  if [ ! -f "$view" ]; then
    echo "FAIL view of $image: $view missing"; failures=$((failures + 1)); continue
  fi
  read -r w1 w2 w3 w4 h1 h2 h3 h4 < <(od -An -tu1 -j16 -N8 "$view")
  width=$(( (w1 << 24) | (w2 << 16) | (w3 << 8) | w4 )) height=$(( (h1 << 24) | (h2 << 16) | (h3 << 8) | h4 ))
  if [ "$width" != 632 ] || [ "$height" != 692 ]; then
    echo "FAIL view of $image: ${width}x${height}, want 632x692"; failures=$((failures + 1))
  else
    echo "ok   view of $(basename "$image"): ${width}x${height}"
  fi
done
# A truncated image is refused by name, with the reason, and the next one
# still runs (its view written).
head -c 3000 "${images[0]}" > "$work/cut.png"
rm -rf "$work/view"
check "truncated image refused" 1 "cut.png: truncated PNG" -- \
  "$detect" --camera "$work/set/camera.yaml" --view "$work/view" "$work/cut.png" "${images[1]}"
if [ -f "$work/view/$(basename "${images[1]}")" ] && [ ! -e "$work/view/cut.png" ]; then
  echo "ok   the image after the truncated one still run"
else
  echo "FAIL the image after the truncated one: view missing, or a view of the truncated one"
  failures=$((failures + 1))
fi
# A small file whose header declares a huge image (a "decompression bomb")
# is refused by its declared size, before anything is decoded.
cp "${images[0]}" "$work/huge.png"
printf '\x00\x00\x9c\x40\x00\x00\x9c\x40' | dd of="$work/huge.png" bs=1 seek=16 conv=notrunc status=none
check "huge declared image refused" 1 "huge.png: image is 40000x40000, the camera's" -- \
  "$detect" --camera "$work/set/camera.yaml" "$work/huge.png" "${images[1]}"
touch "$work/file"
check "view directory refused" 2 "--view $work/file/views: cannot create the directory" -- \
  "$detect" --camera "$work/set/camera.yaml" --view "$work/file/views" "${images[0]}"
finish
