"""A spec with one output of each kind, for the viewer and picture tests."""

#: the paper's arm (two 1 m links about z) with one output of each kind
EVERY_KIND_SPEC = """
    urdf: arm.urdf
    gravity: [0, 0, 0]
    cables:
      - name: c1
        route:
          - {frame: base, point: [0, 0.5, 0]}
          - {frame: link1, point: [0.8, 0.1, 0]}
      - name: c2
        route:
          - {frame: base, point: [0, -0.5, 0]}
          - {frame: link2, point: [0.5, -0.1, 0]}
    outputs:
      - {name: tip_x, frame: tip, component: x}
      - {name: tip_rz, frame: tip, component: rz}
      - {name: elbow, joint: q2}
      - {name: c1_length, cable: c1}
      - name: mid_x
        sum:
          - {weight: 0.5, frame: link2, component: x}
          - {weight: 0.5, frame: tip, component: x}
    poses:
      p: [0.3, 0.4]
    """
