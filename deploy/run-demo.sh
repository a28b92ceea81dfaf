#!/usr/bin/env bash
# Sets everything up on Debian 12 and runs the main job on the built-in
# teacher: synthesises a 2-sensor take of a procedural body doing a front
# kick, starts reenact-server, lets the capture daemon reenactd play the take
# into it over gRPC at the recorded pace, lists and downloads the stored take
# and draws its contact sheet; then submits a rigid body-part reconstruction
# job (voxel-carved parts, thesis 3.4) and follows its progress bar, exports
# the reenactment to glTF, evaluates it against the take's ground truth and
# renders a novel-view video with reenact-viewer; then does the same with the
# statistical body model (thesis ch. 4), whose fitted skeleton is also
# exported as BVH; last, a synthetic learner practises the kick in front of
# reenact-mirror (thesis 4.5.1) with the body-model teacher, which writes the
# mirror video and a repetition report. The server also serves the tablet app
# (--http): the demo prints its address, with a viewer token, and in a
# terminal waits for Enter before it stops the server. Outputs go to
# ./out/demo.
set -euo pipefail
cd "$(dirname "$0")/.."
bash deploy/setup-debian.sh
bash deploy/build.sh
out=out/demo
mkdir -p "$out"
bin=build/bin
reenact=$bin/reenact
viewer=$bin/reenact-viewer

# Like real depth cameras, the synthetic sensors carry no skeleton: the
# daemon's body tracker (--tracker auto, with the body-model refinement on)
# finds it in each sensor's depth, and every job and the mirror use those
# tracked skeletons. The true joints stay on /ground_truth for evaluation.
"$reenact" synth --motion builtin:front-kick --body procedural --sensors 2 --seconds 3 \
  --out "$out/source.mcap"

# Trust: the demo makes its own private CA and server certificate, and a token
# per role; the server speaks TLS only and every call needs a token. The
# capture daemon ingests with the capture token, the coach runs the jobs and
# the viewer and the mirror only read.
# The tablet app (reenact-server --http) is served to the local network too,
# so the certificate also names this machine's first network address.
rm -rf "$out/server" "$out/spool" "$out/server.port" "$out/http.port" "$out/tls"
lan_ip=$(hostname -I 2>/dev/null | awk '{print $1}' || true)
bash deploy/make-certs.sh "$out/tls" ${lan_ip:+"$lan_ip"}
for role in capture coach viewer; do
  "$reenact" auth add --file "$out/tls/tokens.json" --role "$role" --name "demo-$role" \
    > "$out/tls/$role.token"
done
chmod 600 "$out/tls/"*.token
export REENACT_TLS_CA="$out/tls/ca.pem"
coach=(--token-file "$out/tls/coach.token")
# The tablet app's port: 8443 when it is free, else any.
http_port=8443
if (exec 3<> /dev/tcp/127.0.0.1/8443) 2> /dev/null; then http_port=0; fi
"$bin/reenact-server" --data "$out/server" --listen 127.0.0.1:0 --port-file "$out/server.port" \
  --tls-cert "$out/tls/server.pem" --tls-key "$out/tls/server.key" \
  --auth "$out/tls/tokens.json" --http "0.0.0.0:$http_port" --http-port-file "$out/http.port" \
  2> "$out/server.log" &
server_pid=$!
trap 'kill $server_pid 2> /dev/null || true' EXIT
for _ in $(seq 100); do [ -s "$out/server.port" ] && [ -s "$out/http.port" ] && break; sleep 0.1; done
server=$(cat "$out/server.port")
http_port=$(sed 's/.*://' "$out/http.port")
echo "demo: reenact-server listening on $server (data in $out/server)"
echo "demo: the tablet app on https://127.0.0.1:$http_port/ (TLS and tokens, as gRPC)"

# The daemon records the take from its sensors (here: the synthetic take
# played back in real time) and exits once the server has all of it on disk.
"$bin/reenactd" --server "$server" --source "playback:$out/source.mcap" --once \
  --token-file "$out/tls/capture.token" \
  --take-name front-kick --spool "$out/spool" --control 127.0.0.1:0 \
  --tracker auto --tracker-refine on --stats-json "$out/capture-stats.json"

"$reenact" takes list --server "$server" "${coach[@]}"
take_id=$("$reenact" takes list --server "$server" "${coach[@]}" --json | \
  sed -n 's/.*"take_id": "\([^"]*\)".*/\1/p' | head -n 1)
"$reenact" takes show "$take_id" --server "$server" "${coach[@]}"
# Without a token, and with a viewer's token, deleting the take is refused.
"$reenact" takes delete "$take_id" --server "$server" 2>&1 | sed 's/^/demo: refused as expected: /' || true
"$reenact" takes delete "$take_id" --server "$server" --token-file "$out/tls/viewer.token" 2>&1 |
  sed 's/^/demo: refused as expected: /' || true
"$reenact" takes download "$take_id" --server "$server" "${coach[@]}" --out "$out/take.mcap" \
  --quiet
"$reenact" take info "$out/take.mcap"
# How well the daemon's tracker found the teacher, against the true joints.
"$reenact" take skeletons "$out/take.mcap" --truth "$out/source.mcap"
"$reenact" take sheet "$out/take.mcap" --out "$out/sheet.png"

# Reconstruction: a job on the server, run by a reenact-worker process; the
# progress bar follows the job's Watch stream. reconstruct NAME GLB ARGS...
# submits a job with the `jobs submit` arguments ARGS, then shows its
# reenactment, exports it to GLB, evaluates it against the take's ground
# truth and renders a novel view: $out/NAMEjob.json, NAMEeval.json and
# NAMEnovel-view/. The reenactment's id is left in $reenactment_id.
reconstruct() {
  local name=$1 glb=$2
  shift 2
  "$reenact" jobs submit --server "$server" "${coach[@]}" --take "$take_id" "$@" --wait --json \
    > "$out/${name}job.json"
  reenactment_id=$(sed -n 's/.*"reenactment": *"\([^"]*\)".*/\1/p' "$out/${name}job.json" |
    head -n 1)
  "$reenact" reenactments show "$reenactment_id" --server "$server" "${coach[@]}"
  "$reenact" export --server "$server" "${coach[@]}" --reenactment "$reenactment_id" \
    --format glb --out "$glb"
  "$reenact" eval --server "$server" "${coach[@]}" --reenactment "$reenactment_id" \
    --take "$out/source.mcap" \
    --every 3 --json > "$out/${name}eval.json"
  cat "$out/${name}eval.json"
  # The novel-view video: reenact-viewer fetches the reenactment and renders a
  # full turn around the teacher, headless (PNG frames and video.mp4).
  rm -rf "$out/${name}novel-view"
  "$viewer" --server "$server" --token-file "$out/tls/viewer.token" \
    --reenactment "$reenactment_id" --camera orbit \
    --cache "$out/cache" --render-to "$out/${name}novel-view" --width 960 --height 540
}

# Rigid body parts (thesis 3.4): voxel-carved parts with view-dependent textures.
reconstruct "" "$out/reenactment.glb" --method rigid-carved

# The statistical body model (thesis ch. 4) on the same take: the procedural
# body fitted to the merged point clouds of both sensors, refined, textured
# into an atlas; one skinned glTF mesh, and the fitted skeleton as BVH.
reconstruct body- "$out/body.glb" --method body --model procedural
"$reenact" export --server "$server" "${coach[@]}" --reenactment "$reenactment_id" --format bvh \
  --out "$out/body.bvh"

# The magic mirror (thesis 4.5.1). The learner: another body shape, turned
# 90 degrees to their left, standing in guard for 2 s, then doing the kick.
# reenact-mirror reads their facing, and once it has held still for 2 s turns
# the body-model teacher to it and plays it beside the learner's mirror image;
# the repetition is graded part by part (time-aligned by DTW) into a report.
# The learner's sensor gives no skeleton either: the daemon records them and
# tracks them as it did the teacher, and the mirror reads the stored take.
# The mirror compares the learner with the teacher's joints as the same
# tracker (with its model refinement, as the daemon ran) finds them in the
# teacher drawn as depth from the learner's side: the same joint definitions
# on both sides.
"$reenact" synth --motion builtin:front-kick --body procedural --shape random:3 --sensors 1 \
  --seconds 5.5 --lead-in-s 2 --yaw-deg 90 --color-width 960 --color-height 540 \
  --out "$out/learner-source.mcap" --quiet
rm -rf "$out/learner-spool"
"$bin/reenactd" --server "$server" --source "playback:$out/learner-source.mcap" --once \
  --token-file "$out/tls/capture.token" --take-name learner --spool "$out/learner-spool" --control 127.0.0.1:0 \
  --tracker auto --tracker-refine on
learner_id=$("$reenact" takes list --server "$server" "${coach[@]}" --json | \
  sed -n 's/.*"take_id": "\([^"]*-learner-[^"]*\)".*/\1/p' | head -n 1)
"$reenact" takes download "$learner_id" --server "$server" "${coach[@]}" \
  --out "$out/learner.mcap" --quiet
"$reenact" take skeletons "$out/learner.mcap" --truth "$out/learner-source.mcap"
rm -rf "$out/mirror" "$out/mirror-report"
"$bin/reenact-mirror" --server "$server" --token-file "$out/tls/viewer.token" \
  --teacher "$reenactment_id" --cache "$out/cache" \
  --learner-take "$out/learner.mcap" --dtw --render-to "$out/mirror" \
  --report "$out/mirror-report" --width 960 --height 540 --teacher-joints tracked-refined
# The tablet: the app on this machine's address, the viewer token in the
# address's fragment (the page keeps it and never sends it in a URL). The
# tablet must trust the demo's CA first (install ca.pem as a CA certificate).
viewer_token=$(cat "$out/tls/viewer.token")
echo
echo "demo: watch on a tablet on this network (trust $PWD/$out/tls/ca.pem on it first):"
echo "demo:   https://${lan_ip:-127.0.0.1}:$http_port/#token=$viewer_token"
echo "demo:   (on this machine: https://127.0.0.1:$http_port/#token=$viewer_token)"
if [ -t 0 ] && [ -t 1 ]; then
  read -r -p "demo: press Enter to stop reenact-server and finish " _ || true
fi
kill -TERM $server_pid && wait $server_pid || true
trap - EXIT
echo
echo "demo: source take   $PWD/$out/source.mcap"
echo "demo: stored take   $PWD/$out/take.mcap (as reenact-server stored it)"
echo "demo: capture stats $PWD/$out/capture-stats.json"
echo "demo: contact sheet $PWD/$out/sheet.png"
echo "demo: job           $PWD/$out/job.json (rigid-carved)"
echo "demo: evaluation    $PWD/$out/eval.json"
echo "demo: novel view    $PWD/$out/novel-view/video.mp4 (a full turn around the teacher; PNG frames beside it)"
echo "demo: body job      $PWD/$out/body-job.json (body model)"
echo "demo: body skeleton $PWD/$out/body.bvh (BVH, Kinect v2 joints, metres)"
echo "demo: body eval     $PWD/$out/body-eval.json"
echo "demo: body view     $PWD/$out/body-novel-view/video.mp4 (a full turn around the teacher; PNG frames beside it)"
echo "demo: learner take  $PWD/$out/learner.mcap (synthetic, turned 90 degrees; tracked by reenactd)"
echo "demo: mirror        $PWD/$out/mirror/video.mp4 (the learner's mirror image beside the turned teacher)"
echo "demo: mirror report $PWD/$out/mirror-report/rep-001.png (per-part error over time; .csv and .json beside it)"
echo "demo: mirror grade  $PWD/$out/mirror-report/rep-001-heatmap.png (parts x time, grey where not seen), rep-001-worst.png (the worst moments); corrections in rep-001.json"
echo
echo "demo: glTF 2.0 files (any glTF viewer opens them):"
echo "demo: rigid-part reenactment glTF: $PWD/$out/reenactment.glb"
echo "demo: body-model reenactment glTF: $PWD/$out/body.glb"
