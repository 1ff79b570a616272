# make live — the built-in demo body, live in the browser (issue 21; LiCROM's
# interactive application, Fig. 3): the demo's model and cubature (made by
# pipelines/demo.mk if missing), crom-live stepping it on the wall clock and
# crom-view serving it on 127.0.0.1:$(PORT). Press on the body and drag;
# the buttons swap it for the demo's other shapes (the same model on other
# meshes). Ctrl-C ends both (the terminal's SIGINT reaches each; the recipe's
# shell waits for them), the run's stream complete. Run through the
# top-level Makefile (`make live`), which builds first.
#
#   make live                      # the demo's cube
#   make live SHAPE=2 PORT=8000    # its sphere-like superquadric, another port
#   make -f pipelines/live.mk CUB=my-cub.h5 LIVE_FLAGS='--pin bottom'   # any cubature
include $(dir $(lastword $(MAKEFILE_LIST)))demo.mk

SHAPE ?= box
PORT ?= 8780
CUB ?= $(OUT)/cub-$(SHAPE).h5
OFFER ?= $(filter-out $(CUB),$(foreach s,$(TRAIN) $(TEST),$(OUT)/cub-$(s).h5))
# the demo's body: a 1 m superquadric of E = 1 MPa held at the bottom; a
# drag is a spring of DRAG_K N/m (stiff enough that the point under the
# cursor follows it)
DRAG_K ?= 1e7
LIVE_FLAGS ?= --pin bottom --gravity 0,0,0 --dt 0.0166667 --drag-stiffness $(DRAG_K)
# OPEN=no: only print the address (a machine without a display: forward the
# port, ssh -L $(PORT):127.0.0.1:$(PORT) ...)
OPEN ?= yes

.PHONY: live
live: $(CUB) $(OFFER)
	@d=$$(mktemp -d /tmp/crom-live.XXXXXX); trap 'rm -rf "$$d"' EXIT; mkfifo "$$d/frames" "$$d/cmds"; \
	crom-live --cubature $(CUB) $(LIVE_FLAGS) --commands "$$d/cmds" > "$$d/frames" & live=$$!; \
	crom-view --cubature $(CUB) $(foreach o,$(OFFER),--offer $(o)) --port $(PORT) \
	  < "$$d/frames" > "$$d/cmds" & view=$$!; \
	if [ "$(OPEN)" = yes ] && [ "$(PORT)" != 0 ] && [ -n "$${DISPLAY:-}$${WAYLAND_DISPLAY:-}" ] && \
	   command -v xdg-open >/dev/null; then sleep 1; xdg-open http://127.0.0.1:$(PORT)/ >/dev/null 2>&1 || true; fi; \
	trap '' INT TERM; rv=0; rl=0; wait $$view || rv=$$?; wait $$live || rl=$$?; [ $$rv -eq 0 ] && [ $$rl -eq 0 ]
