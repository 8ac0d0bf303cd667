// limbctl live view: the leader gimbal (limbctl/view/leader.py). Draws the leader's pose as a
// diamond beside the follower's markers, and the force a felt leader applies as an arrow toward
// where its wall pushes, with the figure in N m; the side panel gets a bar against the cap.
// A live message without a "leader" part (every source but a leader) leaves the page as it was.
// A three-servo leader's message adds "twist_deg" (and "toward_twist_deg" while it pushes): a row
// with its own twist gauge, -180..180 deg, the leader's twist in teal, the push's in pink.
"use strict";

(function () {
  const COLORS = { leader: "#00897b", push: "#d81b60", bar: "#eeeeee" };
  // Arrow length (px) at no push and at the cap: long enough to see at the cap, short enough
  // not to reach across a 30 deg region on the 900 px plane.
  const ARROW_MIN_PX = 14, ARROW_CAP_PX = 70;
  // Half the diamond's diagonal (px): between the limb's dot (7) and the written ring (11).
  const DIAMOND_PX = 9;

  let panel = null;

  function byId(id) { return document.getElementById(id); }
  function fmtPose(p) { return p ? `${p[0].toFixed(1)}, ${p[1].toFixed(1)}` : "-"; }

  // The panel and the legend's keys, made the first time a leader is seen.
  function build() {
    const style = document.createElement("style");
    style.textContent =
      `.key.leader::before { background: ${COLORS.leader}; height: 10px; width: 10px; transform: rotate(45deg); }\n` +
      `.key.push::before { background: ${COLORS.push}; }\n` +
      `#leader-bar { background: ${COLORS.bar}; border: 1px solid #bbb; height: 12px; width: 100%; }\n` +
      `#leader-bar-fill { background: ${COLORS.push}; height: 100%; width: 0%; }\n` +
      `#leader-panel h2 { margin-top: 0.6em; }\n` +
      `#leader-twist-gauge { background: ${COLORS.bar}; border: 1px solid #bbb; height: 12px; position: relative; width: 100%; }\n` +
      `#leader-twist-gauge div { height: 100%; position: absolute; top: 0; width: 3px; }\n` +
      `#leader-twist-mark { background: ${COLORS.leader}; }\n` +
      `#leader-twist-toward { background: ${COLORS.push}; }`;
    document.head.appendChild(style);
    const legend = byId("legend-teleop");
    const keys = document.createElement("span");
    keys.id = "leader-keys";
    keys.innerHTML = '<span class="key leader">leader (as read)</span>' +
      '<span class="key push">leader\'s push: toward the region, long as its share of the cap</span>';
    legend.insertBefore(keys, byId("steer-hint"));
    const section = document.createElement("section");
    section.id = "leader-panel";
    section.innerHTML = "<h2>Leader</h2><table>" +
      '<tr><th>leader (pan, tilt)</th><td id="leader-pose">-</td></tr>' +
      '<tr><th>pushes back</th><td id="leader-push">-</td></tr>' +
      '<tr><th>of its cap</th><td><div id="leader-bar"><div id="leader-bar-fill"></div></div></td></tr>' +
      '<tr><th>beyond the edge</th><td id="leader-beyond">-</td></tr>' +
      '<tr id="leader-twist-row"><th>leader twist</th><td><span id="leader-twist">-</span>' +
      '<div id="leader-twist-gauge"><div id="leader-twist-mark"></div>' +
      '<div id="leader-twist-toward"></div></div></td></tr>' +
      '<tr><th>feel</th><td id="leader-state">-</td></tr></table>';
    const teleop = byId("teleop");
    teleop.parentElement.insertBefore(section, teleop.nextSibling);
    return { section: section, keys: keys };
  }

  function show(live) {
    const leader = live.leader;
    if (!leader) {
      if (panel) panel.section.hidden = panel.keys.hidden = true;
      return;
    }
    if (!panel) panel = build();
    panel.section.hidden = panel.keys.hidden = false;
    byId("leader-pose").textContent = fmtPose(leader.pose);
    const felt = leader.cap_nm !== null;
    // the push the law allows, and what the motors applied as last read (Present Current)
    const sensed =
      leader.sensed_nm === undefined ? "" : `, sensed ${leader.sensed_nm.toFixed(2)} N m`;
    byId("leader-push").textContent = felt
      ? `${leader.torque_nm.toFixed(2)} N m (cap ${leader.cap_nm.toFixed(2)} N m)${sensed}`
      : "passive: it cannot push";
    const share = felt ? Math.min(1, leader.torque_nm / leader.cap_nm) : 0;
    byId("leader-bar-fill").style.width = `${(100 * share).toFixed(1)}%`;
    byId("leader-bar").parentElement.parentElement.hidden = !felt;
    byId("leader-beyond").textContent =
      leader.beyond_deg === null ? "-" : `${leader.beyond_deg.toFixed(2)} deg`;
    byId("leader-state").textContent = leader.state || "-";
    showTwist(leader);
  }

  // The gauge's position (%) of a twist in -180..180 deg.
  function gaugePercent(deg) { return `calc(${((deg + 180) / 3.6).toFixed(2)}% - 1px)`; }

  function showTwist(leader) {
    const twist = leader.twist_deg, toward = leader.toward_twist_deg;
    const row = byId("leader-twist-row");
    row.hidden = twist === undefined || twist === null;
    if (row.hidden) return;
    byId("leader-twist").textContent = toward === null || toward === undefined
      ? `${twist.toFixed(1)} deg`
      : `${twist.toFixed(1)} deg, pushed toward ${toward.toFixed(1)} deg`;
    byId("leader-twist-mark").style.left = gaugePercent(twist);
    const mark = byId("leader-twist-toward");
    mark.hidden = toward === null || toward === undefined;
    if (!mark.hidden) mark.style.left = gaugePercent(toward);
  }

  function draw(ctx, P, live) {
    const leader = live.leader;
    if (!leader || !leader.pose) return;
    const x = P.x(leader.pose[0]), y = P.y(leader.pose[1]);
    if (leader.torque_nm > 0 && leader.toward && leader.cap_nm) {
      // the push's direction on the canvas: from the leader toward its goal
      const dx = P.x(leader.toward[0]) - x, dy = P.y(leader.toward[1]) - y;
      const norm = Math.hypot(dx, dy);
      if (norm > 0) {
        const share = Math.min(1, leader.torque_nm / leader.cap_nm);
        // length = ARROW_MIN_PX + share * (ARROW_CAP_PX - ARROW_MIN_PX), past the diamond
        const length = ARROW_MIN_PX + share * (ARROW_CAP_PX - ARROW_MIN_PX);
        const ux = dx / norm, uy = dy / norm;
        const x0 = x + ux * DIAMOND_PX, y0 = y + uy * DIAMOND_PX;
        const x1 = x0 + ux * length, y1 = y0 + uy * length;
        ctx.strokeStyle = ctx.fillStyle = COLORS.push;
        ctx.lineWidth = 4;
        ctx.beginPath(); ctx.moveTo(x0, y0); ctx.lineTo(x1, y1); ctx.stroke();
        ctx.beginPath();
        ctx.moveTo(x1 + ux * 8, y1 + uy * 8);
        ctx.lineTo(x1 - uy * 7, y1 + ux * 7);
        ctx.lineTo(x1 + uy * 7, y1 - ux * 7);
        ctx.closePath(); ctx.fill();
        // the figure above and right of the diamond, clear of the follower's markers
        ctx.font = "bold 12px sans-serif";
        ctx.fillText(`${leader.torque_nm.toFixed(2)} N m`, x + DIAMOND_PX + 4, y - DIAMOND_PX - 4);
      }
    }
    ctx.fillStyle = COLORS.leader;
    ctx.beginPath();
    ctx.moveTo(x, y - DIAMOND_PX); ctx.lineTo(x + DIAMOND_PX, y);
    ctx.lineTo(x, y + DIAMOND_PX); ctx.lineTo(x - DIAMOND_PX, y);
    ctx.closePath(); ctx.fill();
  }

  window.limbview.addLayer({ draw: draw, show: show });
})();
