"""Tests of core/retarget.py's joint matching on the skeletons of the rigs users bring (names and hierarchies as
those tools write them; the motions retargeted: tests/formats/test_bvh.py)."""

import pytest

from core.body import SMPL_JOINT_NAMES
from core.retarget import joint_keys, match_joints


def _tree(spec: str):
    """(names, parents) of an indented outline: one joint per line, two spaces a level."""
    names, parents, stack = [], [], []
    for line in spec.strip("\n").splitlines():
        depth = (len(line) - len(line.lstrip())) // 2
        del stack[depth:]
        names.append(line.strip())
        parents.append(stack[-1] if stack else -1)
        stack.append(len(names) - 1)
    return names, parents


def _rig(trunk: list[str], arm: str, leg: str, chest: str, sides=("Left", "Right"), leg_under=0,
         pelvis_above: list[str] = ()):
    """An outline: `pelvis_above` joints, the `trunk` (pelvis, spine..., head) as a chain, each side's `arm`
    (joint names, '{}' the side) under the trunk's joint `chest` and its `leg` under trunk[leg_under]."""
    lines = [("  " * i) + n for i, n in enumerate(pelvis_above)]
    base = len(pelvis_above)
    for i, n in enumerate(trunk):
        lines.append("  " * (base + i) + n)
        for chain, here in ((leg, i == leg_under), (arm, n == chest)):
            if here:
                for side in sides:
                    lines += ["  " * (base + i + 1 + k) + j.format(side) for k, j in enumerate(chain.split())]
    return _tree("\n".join(lines))


RIGS = {
    # name: (outline, {SMPL joint: rig joint} expected, beyond the obvious)
    "mixamo": (_rig(["mixamorig:Hips", "mixamorig:Spine", "mixamorig:Spine1", "mixamorig:Spine2",
                     "mixamorig:Neck", "mixamorig:Head"],
                    "mixamorig:{}Shoulder mixamorig:{}Arm mixamorig:{}ForeArm mixamorig:{}Hand",
                    "mixamorig:{}UpLeg mixamorig:{}Leg mixamorig:{}Foot mixamorig:{}ToeBase", "mixamorig:Spine2"),
               {"pelvis": "mixamorig:Hips", "spine1": "mixamorig:Spine", "spine2": "mixamorig:Spine1",
                "spine3": "mixamorig:Spine2", "neck": "mixamorig:Neck", "left_collar": "mixamorig:LeftShoulder",
                "left_shoulder": "mixamorig:LeftArm", "left_wrist": "mixamorig:LeftHand",
                "left_ankle": "mixamorig:LeftFoot", "left_foot": "mixamorig:LeftToeBase"}),
    "cmu_asf": (_rig(["root", "lowerback", "upperback", "thorax", "lowerneck", "upperneck", "head"],
                     "{}clavicle {}humerus {}radius {}wrist {}hand", "{}hipjoint {}femur {}tibia {}foot {}toes", "thorax",
                     sides=("l", "r")),
                {"pelvis": "root", "spine1": "lowerback", "spine2": "upperback", "spine3": "thorax",
                 "neck": "lowerneck", "left_collar": "lclavicle", "left_shoulder": "lhumerus", "left_elbow": "lradius",
                 "left_wrist": "lwrist", "left_hand": "lhand", "left_hip": "lfemur", "left_ankle": "lfoot",
                 "left_foot": "ltoes"}),
    "xsens": (_rig(["Pelvis", "L5", "L3", "T12", "T8", "Neck", "Head"],
                   "{}Shoulder {}UpperArm {}ForeArm {}Hand", "{}UpperLeg {}LowerLeg {}Foot {}Toe", "T8"),
              {"pelvis": "Pelvis", "spine1": "L5", "spine2": "L3", "spine3": "T8", "left_collar": "LeftShoulder",
               "left_shoulder": "LeftUpperArm", "left_hip": "LeftUpperLeg", "left_foot": "LeftToe"}),
    "daz_genesis": (_rig(["hip", "abdomenLower", "abdomenUpper", "chestLower", "chestUpper", "neckLower",
                          "neckUpper", "head"],
                         "{}Collar {}ShldrBend {}ShldrTwist {}ForearmBend {}ForearmTwist {}Hand",
                         "{}ThighBend {}ThighTwist {}Shin {}Foot {}Toe", "chestUpper", sides=("l", "r")),
                    {"pelvis": "hip", "spine1": "abdomenLower", "spine2": "abdomenUpper", "spine3": "chestUpper",
                     "neck": "neckLower", "left_shoulder": "lShldrBend", "left_elbow": "lForearmBend",
                     "left_hip": "lThighBend", "left_knee": "lShin"}),
    "biped": (_rig(["Bip01 Pelvis", "Bip01 Spine", "Bip01 Spine1", "Bip01 Spine2", "Bip01 Neck", "Bip01 Head"],
                   "Bip01_{}_Clavicle Bip01_{}_UpperArm Bip01_{}_Forearm Bip01_{}_Hand",
                   "Bip01_{}_Thigh Bip01_{}_Calf Bip01_{}_Foot Bip01_{}_Toe0", "Bip01 Neck", sides=("L", "R"), leg_under=1,
                   pelvis_above=["Bip01"]),
              {"pelvis": "Bip01 Pelvis", "spine1": "Bip01 Spine", "spine3": "Bip01 Spine2",
               "left_hip": "Bip01_L_Thigh", "left_foot": "Bip01_L_Toe0", "left_collar": "Bip01_L_Clavicle"}),
    "advanced_skeleton": (_rig(["Root_M", "Spine1_M", "Chest_M", "Neck_M", "Head_M"],
                               "Scapula_{} Shoulder_{} Elbow_{} Wrist_{}", "Hip_{} Knee_{} Ankle_{} Toes_{}", "Chest_M",
                               sides=("L", "R")),
                          {"pelvis": "Root_M", "spine1": "Spine1_M", "spine3": "Chest_M", "neck": "Neck_M",
                           "left_collar": "Scapula_L", "left_shoulder": "Shoulder_L", "left_ankle": "Ankle_L",
                           "left_foot": "Toes_L"}),
    "unreal": (_rig(["root", "pelvis", "spine_01", "spine_02", "spine_03", "neck_01", "head"],
                    "clavicle_{} upperarm_{} lowerarm_{} hand_{}", "thigh_{} calf_{} foot_{} ball_{}", "spine_03",
                    sides=("l", "r"), leg_under=1),
               {"pelvis": "pelvis", "spine1": "spine_01", "spine2": "spine_02", "spine3": "spine_03",
                "left_collar": "clavicle_l", "left_foot": "ball_l"}),
    "mocapbank": (_rig(["Hips", "Chest", "Chest2", "Neck", "Head"], "{}Collar {}Shoulder {}Elbow {}Wrist",
                       "{}Hip {}Knee {}Ankle", "Chest2"),
                  {"pelvis": "Hips", "spine1": "Chest", "spine3": "Chest2", "left_collar": "LeftCollar",
                   "left_shoulder": "LeftShoulder", "left_hip": "LeftHip", "left_ankle": "LeftAnkle"}),
    "smpl_named": (_rig(["pelvis", "spine1", "spine2", "spine3", "neck", "head"],
                        "{}_collar {}_shoulder {}_elbow {}_wrist {}_hand", "{}_hip {}_knee {}_ankle {}_foot", "spine3",
                        sides=("left", "right")),
                   {"pelvis": "pelvis", "spine2": "spine2", "left_shoulder": "left_shoulder",
                    "left_ankle": "left_ankle", "left_foot": "left_foot", "left_wrist": "left_wrist",
                    "left_hand": "left_hand"}),
    "vrm": (_rig(["J_Bip_C_Hips", "J_Bip_C_Spine", "J_Bip_C_Chest", "J_Bip_C_UpperChest", "J_Bip_C_Neck",
                  "J_Bip_C_Head"], "J_Bip_{}_Shoulder J_Bip_{}_UpperArm J_Bip_{}_LowerArm J_Bip_{}_Hand",
                 "J_Bip_{}_UpperLeg J_Bip_{}_LowerLeg J_Bip_{}_Foot J_Bip_{}_ToeBase", "J_Bip_C_UpperChest",
                 sides=("L", "R")),
            {"pelvis": "J_Bip_C_Hips", "spine1": "J_Bip_C_Spine", "spine3": "J_Bip_C_UpperChest",
             "left_collar": "J_Bip_L_Shoulder", "left_shoulder": "J_Bip_L_UpperArm", "left_elbow": "J_Bip_L_LowerArm",
             "left_hip": "J_Bip_L_UpperLeg", "left_knee": "J_Bip_L_LowerLeg", "left_foot": "J_Bip_L_ToeBase"}),
    "optitrack_motive": (_rig(["Hip", "Ab", "Chest", "Neck", "Head"], "{}Shoulder {}UArm {}FArm {}Hand",
                              "{}Thigh {}Shin {}Foot {}Toe", "Chest", sides=("L", "R")),
                         {"pelvis": "Hip", "spine1": "Ab", "spine3": "Chest", "left_collar": "LShoulder",
                          "left_shoulder": "LUArm", "left_elbow": "LFArm", "left_wrist": "LHand", "left_hip": "LThigh",
                          "left_knee": "LShin", "left_ankle": "LFoot", "left_foot": "LToe"}),
    "optitrack_fbx": (_rig(["Skeleton1_Hip", "Skeleton1_Ab", "Skeleton1_Chest", "Skeleton1_Neck", "Skeleton1_Head"],
                           "Skeleton1_{}Shoulder Skeleton1_{}UArm Skeleton1_{}FArm Skeleton1_{}Hand",
                           "Skeleton1_{}Thigh Skeleton1_{}Shin Skeleton1_{}Foot Skeleton1_{}Toe", "Skeleton1_Chest",
                           sides=("L", "R")),
                      {"pelvis": "Skeleton1_Hip", "left_shoulder": "Skeleton1_LUArm", "left_elbow": "Skeleton1_LFArm",
                       "left_knee": "Skeleton1_LShin"}),
    "humanik": (_rig(["Character1_Hips", "Character1_Spine", "Character1_Spine1", "Character1_Spine2",
                      "Character1_Neck", "Character1_Head"],
                     "Character1_{}Shoulder Character1_{}Arm Character1_{}ForeArm Character1_{}Hand",
                     "Character1_{}UpLeg Character1_{}Leg Character1_{}Foot Character1_{}ToeBase", "Character1_Spine2",
                     pelvis_above=["Character1_Reference"]),
                {"pelvis": "Character1_Hips", "spine3": "Character1_Spine2", "left_collar": "Character1_LeftShoulder",
                 "left_shoulder": "Character1_LeftArm", "left_hip": "Character1_LeftUpLeg",
                 "left_foot": "Character1_LeftToeBase"}),
    "kinect": (_rig(["SpineBase", "SpineMid", "SpineShoulder", "Neck", "Head"], "Shoulder{} Elbow{} Wrist{} Hand{}",
                    "Hip{} Knee{} Ankle{} Foot{}", "SpineShoulder"),
               {"pelvis": "SpineBase", "spine1": "SpineMid", "spine3": "SpineShoulder", "left_shoulder": "ShoulderLeft",
                "left_elbow": "ElbowLeft", "left_wrist": "WristLeft", "left_hand": "HandLeft", "left_hip": "HipLeft",
                "left_ankle": "AnkleLeft", "left_foot": "FootLeft"}),
    "meta_body_tracking": (_rig(["FullBody_Hips", "FullBody_SpineLower", "FullBody_SpineMiddle", "FullBody_SpineUpper",
                                 "FullBody_Chest", "FullBody_Neck", "FullBody_Head"],
                                "FullBody_{}Shoulder FullBody_{}Scapula FullBody_{}ArmUpper FullBody_{}ArmLower "
                                "FullBody_{}HandWristTwist FullBody_{}HandWrist",
                                "FullBody_{}UpperLeg FullBody_{}LowerLeg FullBody_{}FootAnkleTwist "
                                "FullBody_{}FootAnkle "
                                "FullBody_{}FootSubtalar FullBody_{}FootTransverse FullBody_{}FootBall",
                                "FullBody_Chest"),
                           {"pelvis": "FullBody_Hips", "spine3": "FullBody_Chest",
                            "left_shoulder": "FullBody_LeftArmUpper", "left_elbow": "FullBody_LeftArmLower",
                            "left_wrist": "FullBody_LeftHandWrist", "left_hip": "FullBody_LeftUpperLeg",
                            "left_knee": "FullBody_LeftLowerLeg", "left_ankle": "FullBody_LeftFootAnkle",
                            "left_foot": "FullBody_LeftFootBall"}),
    "makehuman": (_rig(["root", "spine05", "spine04", "spine03", "spine02", "spine01", "neck01", "neck02", "head"],
                       "clavicle.{} shoulder01.{} upperarm01.{} upperarm02.{} lowerarm01.{} lowerarm02.{} wrist.{}",
                       "pelvis.{} upperleg01.{} upperleg02.{} lowerleg01.{} lowerleg02.{} foot.{} toe1-1.{}",
                       "spine01", sides=("L", "R")),
                  {"pelvis": "root", "spine1": "spine05", "spine3": "spine01", "neck": "neck01",
                   "left_collar": "clavicle.L", "left_shoulder": "upperarm01.L", "left_elbow": "lowerarm01.L",
                   "left_wrist": "wrist.L", "left_hip": "upperleg01.L", "left_knee": "lowerleg01.L",
                   "left_ankle": "foot.L"}),
    "arkit": (_rig(["hips_joint", "spine_1_joint", "spine_2_joint", "spine_3_joint", "spine_4_joint", "spine_5_joint",
                    "spine_6_joint", "spine_7_joint", "neck_1_joint", "neck_2_joint", "neck_3_joint", "neck_4_joint",
                    "head_joint"],
                   "{}_shoulder_1_joint {}_arm_joint {}_forearm_joint {}_hand_joint",
                   "{}_upLeg_joint {}_leg_joint {}_foot_joint {}_toes_joint {}_toesEnd_joint", "spine_7_joint",
                   sides=("left", "right"), pelvis_above=["root"]),
              {"pelvis": "hips_joint", "spine1": "spine_1_joint", "spine3": "spine_7_joint", "neck": "neck_1_joint",
               "head": "head_joint", "left_shoulder": "left_arm_joint", "left_elbow": "left_forearm_joint",
               "left_wrist": "left_hand_joint", "left_hip": "left_upLeg_joint", "left_knee": "left_leg_joint",
               "left_ankle": "left_foot_joint", "left_foot": "left_toes_joint"}),
    "maya_jnt": (_rig(["root_jnt", "spine_01_jnt", "spine_02_jnt", "chest_jnt", "neck_jnt", "head_jnt"],
                      "{}_clavicle_jnt {}_shoulder_bind_jnt {}_elbow_bind_jnt {}_wrist_bind_jnt",
                      "{}_hip_jnt {}_knee_jnt {}_ankle_jnt {}_ball_jnt", "chest_jnt", sides=("L", "R")),
                 {"pelvis": "root_jnt", "spine3": "chest_jnt", "left_collar": "L_clavicle_jnt",
                  "left_shoulder": "L_shoulder_bind_jnt", "left_elbow": "L_elbow_bind_jnt",
                  "left_wrist": "L_wrist_bind_jnt", "left_hip": "L_hip_jnt", "left_ankle": "L_ankle_jnt",
                  "left_foot": "L_ball_jnt"}),
    "roblox_r15": (_rig(["HumanoidRootPart", "LowerTorso", "UpperTorso", "Head"], "{}UpperArm {}LowerArm {}Hand",
                        "{}UpperLeg {}LowerLeg {}Foot", "UpperTorso", leg_under=1),
                   {"pelvis": "LowerTorso", "spine1": "UpperTorso", "left_shoulder": "LeftUpperArm",
                    "left_elbow": "LeftLowerArm", "left_wrist": "LeftHand", "left_hip": "LeftUpperLeg",
                    "left_knee": "LeftLowerLeg", "left_ankle": "LeftFoot"}),
    "second_life": (_rig(["hip", "abdomen", "chest", "neck", "head"], "{}Collar {}Shldr {}ForeArm {}Hand",
                         "{}Thigh {}Shin {}Foot", "chest", sides=("l", "r")),
                    {"pelvis": "hip", "spine1": "abdomen", "spine3": "chest", "left_collar": "lCollar",
                     "left_shoulder": "lShldr", "left_elbow": "lForeArm", "left_hip": "lThigh", "left_knee": "lShin"}),
    "second_life_bento": (_rig(["mPelvis", "mTorso", "mChest", "mNeck", "mHead"],
                               "mCollar{} mShoulder{} mElbow{} mWrist{}", "mHip{} mKnee{} mAnkle{} mFoot{}", "mChest"),
                          {"pelvis": "mPelvis", "spine1": "mTorso", "spine3": "mChest", "left_collar": "mCollarLeft",
                           "left_shoulder": "mShoulderLeft", "left_elbow": "mElbowLeft", "left_wrist": "mWristLeft",
                           "left_hip": "mHipLeft", "left_ankle": "mAnkleLeft", "left_foot": "mFootLeft"}),
    "rigify": (_rig(["DEF-spine", "DEF-spine.001", "DEF-spine.002", "DEF-spine.003", "DEF-spine.004", "DEF-spine.005",
                     "DEF-spine.006"],
                    "DEF-shoulder.{} DEF-upper_arm.{} DEF-upper_arm.{}.001 DEF-forearm.{} DEF-forearm.{}.001 "
                    "DEF-hand.{}", "DEF-thigh.{} DEF-thigh.{}.001 DEF-shin.{} DEF-shin.{}.001 DEF-foot.{} DEF-toe.{}",
                    "DEF-spine.003", sides=("L", "R")),
               {"pelvis": "DEF-spine", "spine1": "DEF-spine.001", "spine3": "DEF-spine.003", "neck": "DEF-spine.004",
                "head": "DEF-spine.006", "left_collar": "DEF-shoulder.L", "left_shoulder": "DEF-upper_arm.L",
                "left_elbow": "DEF-forearm.L", "left_wrist": "DEF-hand.L", "left_hip": "DEF-thigh.L",
                "left_knee": "DEF-shin.L", "left_ankle": "DEF-foot.L", "left_foot": "DEF-toe.L"}),
}


@pytest.mark.parametrize("rig", sorted(RIGS))
def test_each_rigs_joints_match_smpls_by_name_and_the_spine_by_shape(rig):
    """Mixamo's (its 'LeftShoulder' the collar), CMU's ASF names, Xsens', Daz Genesis' (bend and twist joints),
    3ds Max Biped's (a root above the pelvis, the thighs under the spine), AdvancedSkeleton's ('_M', the middle),
    Unreal's (side suffixes, a root at the floor), MocapBank's ('LeftShoulder' the upper arm beside a collar, no
    toes), VRoid's VRM ('J_Bip_L_UpperLeg'), SMPL's own names (its 'left_foot' the toes, 'left_hand' the knuckles
    beside a wrist), OptiTrack Motive's ('LUArm', 'LFArm'; as its FBX writes them, 'Skeleton1_' before each),
    MotionBuilder's HumanIK ('Character1_' before each), Kinect's (the side a word at the end: 'KneeLeft'), Meta's
    body tracking ('FullBody_LeftArmUpper'), MakeHuman's ('upperarm01.L', beside its twist joint) and Blender
    Rigify's deform bones (the head and neck numbered along the spine: 'DEF-spine.006'), Apple ARKit's
    ('left_upLeg_joint'), a Maya rig's ('L_elbow_bind_jnt'), Roblox's R15 ('LeftUpperLeg' under 'LowerTorso') and
    Second Life's (its BVH names, 'lShldr', and its Bento skeleton's, 'mHipLeft') each match SMPL's joints as
    their rigs mean them; every match of the left side has its right."""
    (names, parents), expected = RIGS[rig]
    match = {SMPL_JOINT_NAMES[k]: names[j] for k, j in match_joints(names, parents, "rig").items()}
    for smpl, name in expected.items():
        assert match.get(smpl) == name, (smpl, match)
    key = dict(zip(names, joint_keys(names)))
    for smpl in match:
        if smpl.startswith("left_"):
            right = smpl.replace("left_", "right_")
            assert key[match[right]] == "r" + key[match[smpl]][1:], (smpl, match)
    assert {"pelvis", "head", "left_hip", "left_knee", "left_ankle", "left_shoulder", "left_elbow",
            "left_wrist"} <= set(match)
