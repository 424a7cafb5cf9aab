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
# camera views 346 x 466 pixels (the region and its guard band).
for image in "${images[@]}"; do
  view="$work/view/$(basename "${image%.png}").png"
  if [ ! -f "$view" ]; then
    echo "FAIL view of $image: $view missing"; failures=$((failures + 1)); continue
  fi
  read -r w1 w2 w3 w4 h1 h2 h3 h4 < <(od -An -tu1 -j16 -N8 "$view")
  width=$(( (w1 << 24) | (w2 << 16) | (w3 << 8) | w4 )) height=$(( (h1 << 24) | (h2 << 16) | (h3 << 8) | h4 ))
  if [ "$width" != 932 ] || [ "$height" != 692 ]; then
    echo "FAIL view of $image: ${width}x${height}, want 932x692"; failures=$((failures + 1))
  else
    echo "ok   view of $(basename "$image"): ${width}x${height}"
  fi
done
# A truncated image is refused by name, with the reason, and the next one
# still runs (its view written).
head -c 3000 "${images[0]}" > "$work/cut.png"
rm -rf "$work/view"
check "truncated image refused" 2 "cut.png: truncated PNG" -- \
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
check "huge declared image refused" 2 "huge.png: image is 40000x40000, the camera's" -- \
  "$detect" --camera "$work/set/camera.yaml" "$work/huge.png" "${images[1]}"
touch "$work/file"
check "view directory refused" 1 "--view $work/file/views: cannot create the directory" -- \
  "$detect" --camera "$work/set/camera.yaml" --view "$work/file/views" "${images[0]}"
# Bad input is status 2, an output not written 1, each named with the reason.
check "directory as image" 2 "^markloop-detect: $work: is a directory, not an image" -- \
  "$detect" --camera "$work/set/camera.yaml" "$work" "${images[0]}"
check "directory as calibration" 2 "^markloop-detect: $work: is a directory, not a calibration file" -- \
  "$detect" --camera "$work" "${images[0]}"
mkdir -p "$work/full-view" && ln -sf /dev/full "$work/full-view/$(basename "${images[0]}")"
check "view on a full disk" 1 "full-view/$(basename "${images[0]}"): cannot write: No space left on device" -- \
  "$detect" --camera "$work/set/camera.yaml" --view "$work/full-view" "${images[0]}"
cp "${images[0]}" "$work/input.png" && cp "${images[0]}" "$work/input.keep"
check "view would overwrite the image" 2 "$work/input.png: the view of $work/input.png would overwrite an input image" -- \
  "$detect" --camera "$work/set/camera.yaml" --view "$work" "$work/input.png"
cmp -s "$work/input.png" "$work/input.keep" || { echo "FAIL the input image was overwritten"; failures=$((failures + 1)); }
mkfifo "$work/fifo.png" && (timeout 20 cat "${images[0]}" >"$work/fifo.png" 2>/dev/null &)
check "image through a pipe" 0 "\"image\": \"fifo.png\"" -- "$detect" --camera "$work/set/camera.yaml" "$work/fifo.png"
check "no image" 2 "no image given: IMAGE... is required" -- "$detect" --camera "$work/set/camera.yaml"
check "full disk (standard output)" 1 "standard output: cannot write: No space left on device" -- \
  bash -c '"$1" --camera "$2" "$3" >/dev/full' - "$detect" "$work/set/camera.yaml" "${images[0]}"
finish
