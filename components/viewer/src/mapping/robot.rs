//! Loki's body and eyes: the link tree from the joint states through the URDF, the head
//! camera's images under its optical frame, the ball's track, reach goals and their status.

use super::*;

impl Mapper {
    /// The whole robot at rest (q = 0 for every movable joint) plus its collision geometry, once.
    pub(super) fn draw_robot(&mut self, out: &mut Vec<Logged>) {
        if self.robot_drawn {
            return;
        }
        let Some(robot) = &self.robot else { return };
        self.robot_drawn = true;
        for j in &robot.joints {
            let path = &self.link_paths[j.child];
            let iso = j.transform(0.0);
            if j.kind.is_movable() {
                out.push(Logged::new(path.clone(), tr(&iso)));
            } else {
                out.push(Logged::fixed(path.clone(), tr(&iso)));
            }
        }
        let grey = rerun::Color::from_unmultiplied_rgba(160, 160, 175, 160);
        for (li, link) in robot.links.iter().enumerate() {
            for (i, c) in link.collision.iter().enumerate() {
                let path = format!("{}/collision/{i}", self.link_paths[li]);
                let shape: Option<Box<dyn AsComponents + Send>> = match &c.shape {
                    Shape::Box { size_m } => Some(Box::new(
                        rerun::Boxes3D::from_sizes([v3(*size_m)]).with_colors([grey]),
                    )),
                    Shape::Cylinder { radius_m, length_m } => Some(Box::new(
                        rerun::Cylinders3D::from_lengths_and_radii(
                            [*length_m as f32],
                            [*radius_m as f32],
                        )
                        .with_colors([grey]),
                    )),
                    Shape::Capsule { radius_m, length_m } => Some(Box::new(
                        // rerun's capsule runs from its origin along +z; URDF's is centred.
                        rerun::Capsules3D::from_lengths_and_radii(
                            [*length_m as f32],
                            [*radius_m as f32],
                        )
                        .with_translations([[0.0, 0.0, -(*length_m as f32) / 2.0]])
                        .with_colors([grey]),
                    )),
                    Shape::Sphere { radius_m } => Some(Box::new(
                        rerun::Ellipsoids3D::from_radii([*radius_m as f32]).with_colors([grey]),
                    )),
                    // Meshes are not drawn (robocog does no mesh collision either).
                    Shape::Mesh { .. } => None,
                };
                if let Some(data) = shape {
                    out.push(Logged::fixed(path.clone(), tr(&c.origin.to_iso())));
                    out.push(Logged {
                        path,
                        is_static: true,
                        data,
                    });
                }
            }
        }
    }

    pub(super) fn joint_states(&mut self, m: &body::JointStates, out: &mut Vec<Logged>) {
        self.draw_robot(out);
        let Some(robot) = &self.robot else { return };
        for js in &m.joints {
            let Ok(j) = robot.joint(&js.name) else {
                continue;
            };
            if !js.position.is_finite() {
                continue;
            }
            out.push(Logged::new(
                self.link_paths[j.child].clone(),
                tr(&j.transform(js.position)),
            ));
        }
    }

    pub(super) fn rgbd(
        &mut self,
        topic: &str,
        m: vision::RgbdFrame,
        receipt_ns: i64,
        out: &mut Vec<Logged>,
    ) -> Result<(), MapError> {
        if !m.is_consistent() {
            return Err(MapError::Invalid {
                topic: topic.to_string(),
                reason: format!(
                    "frame {}x{} with {} RGB and {} depth bytes",
                    m.width,
                    m.height,
                    m.rgb.len(),
                    m.depth_mm.len()
                ),
            });
        }
        if self.options.image_hz > 0.0 {
            let st = self.stats.entry(topic.to_string()).or_default();
            let min_gap = (1e9 / self.options.image_hz) as i64;
            if st.last_image_ns != 0 && receipt_ns - st.last_image_ns < min_gap {
                st.thinned += 1;
                return Ok(());
            }
            st.last_image_ns = receipt_ns;
        }
        self.draw_robot(out);
        let cam = self.camera_path(&m.header.frame_id);
        let mut k = [
            m.intrinsics.fx,
            m.intrinsics.fy,
            m.intrinsics.cx,
            m.intrinsics.cy,
        ];
        if !(k[0] > 0.0 && k[1] > 0.0)
            && let Some(c) = self
                .robot
                .as_ref()
                .and_then(|r| r.cameras.iter().find(|c| c.frame == m.header.frame_id))
        {
            k = [c.fx, c.fy, c.cx, c.cy];
        }
        if k[0] > 0.0 && k[1] > 0.0 && self.pinholes.get(&cam) != Some(&(m.width, m.height, k)) {
            self.pinholes.insert(cam.clone(), (m.width, m.height, k));
            out.push(Logged::new(
                cam.clone(),
                rerun::Pinhole::from_focal_length_and_resolution(
                    [k[0] as f32, k[1] as f32],
                    [m.width as f32, m.height as f32],
                )
                .with_principal_point([k[2] as f32, k[3] as f32])
                .with_image_plane_distance(0.5),
            ));
        }
        let res = [m.width, m.height];
        out.push(Logged::new(
            format!("{cam}/rgb"),
            rerun::Image::from_rgb24(m.rgb, res),
        ));
        out.push(Logged::new(
            format!("{cam}/depth"),
            rerun::DepthImage::from_gray16(m.depth_mm, res).with_meter(1000.0),
        ));
        Ok(())
    }

    pub(super) fn push_trajectory(&mut self, path: &str, p: [f32; 3], out: &mut Vec<Logged>) {
        let cap = self.options.trajectory_len.max(2);
        let tr = self.trajectories.entry(path.to_string()).or_default();
        tr.push_back(p);
        while tr.len() > cap {
            tr.pop_front();
        }
        if tr.len() >= 2 {
            let strip: Vec<[f32; 3]> = tr.iter().copied().collect();
            out.push(Logged::new(
                format!("{path}/trajectory"),
                rerun::LineStrips3D::new([strip])
                    .with_colors([ORANGE])
                    .with_radii([0.004]),
            ));
        }
    }

    pub(super) fn ball_track(&mut self, m: &tracking::BallTrack, out: &mut Vec<Logged>) {
        let cam = self.camera_path(&m.header.frame_id);
        let window = format!("{cam}/ball_window");
        let label = format!("{:?} {:.2}", m.state, m.confidence);
        if m.found {
            let w = m.window;
            out.push(Logged::new(
                window,
                rerun::Boxes2D::from_mins_and_sizes(
                    [[w.x as f32, w.y as f32]],
                    [[w.width as f32, w.height as f32]],
                )
                .with_colors([YELLOW])
                .with_labels([label.clone()]),
            ));
        } else {
            out.push(Logged::new(window, rerun::Clear::flat()));
        }
        let r = (m.diameter_m / 2.0).max(0.01) as f32;
        if m.found && m.has_centre_world {
            let p = v3(m.centre_world_m);
            out.push(Logged::new(
                "world/ball",
                rerun::Points3D::new([p])
                    .with_radii([r])
                    .with_colors([ORANGE])
                    .with_labels([label]),
            ));
            self.push_trajectory("world/ball", p, out);
        } else if m.found && m.has_centre_m {
            let path = format!("{}/ball", self.frame_path(&m.header.frame_id));
            let p = v3(m.centre_m);
            out.push(Logged::new(
                path.clone(),
                rerun::Points3D::new([p])
                    .with_radii([r])
                    .with_colors([ORANGE])
                    .with_labels([label]),
            ));
            self.push_trajectory(&path, p, out);
        }
    }

    pub(super) fn reach_goal(&mut self, m: &body::ReachGoal, out: &mut Vec<Logged>) {
        let part = path_part(&m.body_part);
        out.push(Logged::new(
            "log/reach",
            text(if m.active {
                format!(
                    "goal #{} from {}: {} {:?} to {:?} in {}{}",
                    m.id,
                    m.client,
                    m.body_part,
                    m.kind,
                    m.position_m,
                    m.frame,
                    if m.follow { " (follow)" } else { "" }
                )
            } else {
                format!("goal #{} from {}: cancel {}", m.id, m.client, m.body_part)
            }),
        ));
        let path = format!("world/reach/{part}/goal");
        if m.active && m.frame == "world" {
            out.push(Logged::new(
                path,
                rerun::Points3D::new([v3(m.position_m)])
                    .with_radii([0.015])
                    .with_colors([BLUE])
                    .with_labels([format!("goal #{}", m.id)]),
            ));
        } else if !m.active {
            out.push(Logged::new(path, rerun::Clear::flat()));
        }
    }

    pub(super) fn reach_status(&mut self, m: &body::ReachStatus, out: &mut Vec<Logged>) {
        use body::ReachState as S;
        let part = path_part(&m.body_part);
        let colour = match m.state {
            S::Moving => YELLOW,
            S::Reached => GREEN,
            S::Unreachable => RED,
            S::Cancelled => GREY,
            S::Failed => rerun::Color::from_rgb(200, 0, 200),
        };
        let label = format!("#{} {:?}", m.id, m.state);
        let line = format!(
            "#{} {} {:?}: residual {:.3} m, distance {:.3} m {}",
            m.id, m.body_part, m.state, m.residual_m, m.distance_m, m.detail
        );
        out.push(Logged::new(
            "log/reach",
            if matches!(m.state, S::Unreachable | S::Failed) {
                warn(line)
            } else {
                text(line)
            },
        ));
        if matches!(m.state, S::Cancelled | S::Failed) {
            return;
        }
        out.push(Logged::new(
            format!("world/reach/{part}/target"),
            rerun::Points3D::new([v3(m.target_world_m)])
                .with_radii([0.02])
                .with_colors([colour])
                .with_labels([label.clone()]),
        ));
        out.push(Logged::new(
            format!("world/reach/{part}/tip"),
            rerun::Points3D::new([v3(m.tip_world_m)])
                .with_radii([0.01])
                .with_colors([colour]),
        ));
        if matches!(m.state, S::Reached | S::Unreachable) {
            // A lasting mark where the outcome happened.
            out.push(Logged::new(
                format!(
                    "world/reach/{part}/{}",
                    if m.state == S::Reached {
                        "reached"
                    } else {
                        "unreachable"
                    }
                ),
                rerun::Points3D::new([v3(m.target_world_m)])
                    .with_radii([0.025])
                    .with_colors([colour])
                    .with_labels([label]),
            ));
        }
    }
}
