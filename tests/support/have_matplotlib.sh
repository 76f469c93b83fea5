# Sourced by the end-to-end scripts: true when a Python the CLI would pick
# for its plots (see plot_python() in lab/plot.cpp) has matplotlib.
have_matplotlib() {
  local py
  for py in ${BROADPHASE_PYTHON:-} /usr/bin/python3 python3; do
    "$py" -c 'import matplotlib' >/dev/null 2>&1 && return 0
  done
  return 1
}
