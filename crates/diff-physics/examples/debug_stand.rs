use diff_physics::mujoco::{MujocoEngine, MujocoSettings};
use diff_physics::*;
fn main() {
    let model = robot_model::RobotModel::h1_2().unwrap();
    println!("lowest z at standing {:?}", model.lowest_point_z(&robot_model::GenCoords::standing(&model)));
    for integ in ["implicitfast", "Euler", "RK4"] {
        let common = CommonSettings { armature: true, ..CommonSettings::rigid_body_only() };
        let mut e = MujocoEngine::new(&model, &common, &MujocoSettings { integrator: integ.into(), ..Default::default() }).unwrap();
        let mut s = State::standing(&model);
        s.base_pos[2] += 1.0;
        s.dq = (0..27).map(|i| ((i as f64) * 0.37).sin()).collect();
        e.reset(&s).unwrap();
        let e0 = e.energy();
        for _ in 0..500 { e.step(&vec![0.0; 27]).unwrap(); }
        let e1 = e.energy();
        println!("{integ}: E0 {:?} E1 {:?} dE/KE0 {}", e0, e1, (e1.total() - e0.total()) / e0.kinetic);
    }
    let mut e = MujocoEngine::new(&model, &CommonSettings::default(), &MujocoSettings::default()).unwrap();
    e.reset(&State::standing(&model)).unwrap();
    let pd = PdTarget::hold_standing(&model);
    for i in 0..750 {
        let s = e.state();
        let tau = pd_torques(&model, &pd, &s.q, &s.dq);
        e.step(&tau).unwrap();
        if i % 50 == 0 {
            let cs = e.contacts();
            let f: f64 = cs.iter().map(|c| c.normal_force).sum();
            println!("t {:.3} z {:.4} quat {:?} ncon {} fn {:.1} bodies {:?}", e.time(), s.base_pos[2], s.base_quat.map(|x| (x*1000.0).round()/1000.0), cs.len(), f, cs.iter().map(|c| c.body_b.clone()).collect::<std::collections::BTreeSet<_>>());
        }
    }
}
