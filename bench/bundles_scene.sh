# Sourced by bench scripts: bundles_scene UMBRA DIR NAME N POINTS LINE_WIDTH WIDTH HEIGHT writes
# DIR/NAME.tck (`umbra synth bundles --n N --points POINTS`) and DIR/NAME.toml, a scene drawing it
# as LineAO lines coloured by direction, LINE_WIDTH pixels wide, at WIDTH x HEIGHT.
bundles_scene() {
  local u=$1 dir=$2 name=$3 n=$4 points=$5 lw=$6 w=$7 h=$8
  "$u" synth bundles --n "$n" --points "$points" -o "$dir/$name.tck" > /dev/null || return 1
  cat > "$dir/$name.toml" <<SCENE
background = [1.0, 1.0, 1.0]
[camera]
azimuth = -125.0
elevation = 30.0
[[lines]]
path = "$name.tck"
color = "direction"
width = $lw
[render]
method = "lineao"
width = $w
height = $h
SCENE
}
