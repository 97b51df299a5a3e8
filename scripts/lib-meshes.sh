# Shell helper (sourced by evaluate.sh and multiview-eval.sh): the evaluation meshes.
# fetch_eval_meshes: needs BUILD_DIR, SHARED and EVAL_MESHES; fetches the CGAL meshes into
# $BUILD_DIR/eval-meshes and sets meshes_dir, bunny_mesh and scan_args (the --mesh NAME=PATH
# flags of mlsreg-scan, also taken by scripts/multiview_eval.py).
fetch_eval_meshes() {
  meshes_dir=$BUILD_DIR/eval-meshes
  mkdir -p "$meshes_dir"
  bunny_mesh=$SHARED/data/real/stanford_bunny/reconstruction/bun_zipper.ply
  local cgal_meshes=() m
  for m in $EVAL_MESHES; do [ "$m" = bunny ] || cgal_meshes+=("$m"); done
  [ ${#cgal_meshes[@]} -eq 0 ] || bash scripts/fetch-cgal-meshes.sh "$meshes_dir" "${cgal_meshes[@]}"
  scan_args=()
  for m in $EVAL_MESHES; do
    if [ "$m" = bunny ]; then scan_args+=(--mesh "bunny=$bunny_mesh"); else scan_args+=(--mesh "$m=$meshes_dir/$m.off"); fi
  done
}
